"""A rosbag2 folder, as ``ros2 bag record -s mcap`` writes one: ``metadata.yaml`` and the
``.mcap`` files it lists (``walk_0.mcap``, ``walk_1.mcap``, ... where the recording was split by
size or duration). ``bag_files`` finds the files of a folder, in the walk's order, for
``rosbag.McapSource`` to read as one walk; ``metadata_yaml`` writes the metadata of a folder that
``write.WalkRecorder`` recorded, in rosbag2's version 5 (Humble's, read by every later release).

Read: the files ``rosbag2_bagfile_information.relative_file_paths`` lists, in that order; a
folder of ``.mcap`` files without ``metadata.yaml`` (cut or copied by hand), in file-name order
(numbers by value: ``walk_2`` before ``walk_10``), with a note. Refused in one line: sqlite3
storage (``.db3``, Humble's default; ``ros2 bag convert`` makes an MCAP copy) and compressed bags.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from efficienteqa.envs.recorded.mcapwalk import FIX_MCAP
from efficienteqa.errors import EfficientEQAError, first_line

METADATA_FILE = "metadata.yaml"
METADATA_VERSION = 5  # Humble's; Iron and later read it too
FIX_METADATA = (f"give the folder as ros2 bag record wrote it, or remove {METADATA_FILE} to read "
                "its .mcap files in file-name order")
# A topic's offered QoS as rosbag2 5 writes it (a YAML text inside the YAML): keep last, reliable,
# volatile, no deadline, lifespan or lease (rmw's "infinite" durations), automatic liveliness.
_INFINITE = "\n    sec: 9223372036\n    nsec: 854775807"
OFFERED_QOS = ("- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n  deadline:"
               f"{_INFINITE}\n  lifespan:{_INFINITE}\n  liveliness: 1\n"
               f"  liveliness_lease_duration:{_INFINITE}\n  avoid_ros_namespace_conventions: false")


def _convert_fix(folder: Path) -> str:
    name = folder.resolve().name
    return (f"convert it to MCAP with ROS 2: ros2 bag convert -i {folder} -o to_mcap.yaml, where "
            f"to_mcap.yaml holds output_bags: [{{uri: {name}_mcap, storage_id: mcap}}]; "
            f"then read recorded:{name}_mcap")


def _natural(path: Path) -> list[Any]:
    """File-name order with numbers by value (``walk_2.mcap`` before ``walk_10.mcap``)."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part)
            for part in re.split(r"(\d+)", path.name)]


def bag_files(folder: Path) -> tuple[list[Path], str] | None:
    """The ``.mcap`` files of the rosbag2 folder ``folder`` in the walk's order, and a note (""
    when ``metadata.yaml`` lists them); None when the folder holds no bag at all."""
    metadata = folder / METADATA_FILE
    if metadata.is_file():
        return _listed(folder, metadata), ""
    try:
        entries = [p for p in folder.iterdir() if p.is_file()]
    except OSError as error:
        raise EfficientEQAError(f"cannot read the folder {folder}: {error.strerror or error}",
                                fix="give a folder you can read") from None
    mcaps = sorted((p for p in entries if p.suffix.lower() == ".mcap"), key=_natural)
    if mcaps:
        names = [p.name for p in mcaps]
        shown = ", ".join(names) if len(names) <= 4 else f"{names[0]}, ..., {names[-1]}"
        return mcaps, (f"no {METADATA_FILE}: its {len(names)} .mcap "
                       f"file{'s' if len(names) > 1 else ''} read in file-name order ({shown})")
    if any(p.suffix.lower() == ".db3" for p in entries):
        raise EfficientEQAError(f"{folder} holds a rosbag2 recording in sqlite3 storage (.db3); "
                                "only MCAP storage is read", fix=_convert_fix(folder))
    return None


def _yaml(path: Path) -> Any:
    try:
        import yaml
    except ImportError:
        raise EfficientEQAError(f"reading {path} needs PyYAML, which is not installed",
                                fix=f"{FIX_MCAP.partition(' (')[0]} (it brings PyYAML)") from None
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        raise EfficientEQAError(f"cannot read {path}: {first_line(error)}",
                                fix=FIX_METADATA) from None


def _listed(folder: Path, metadata: Path) -> list[Path]:
    data = _yaml(metadata)
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise EfficientEQAError(f"{metadata} has no rosbag2_bagfile_information",
                                fix=FIX_METADATA)
    storage = str(info.get("storage_identifier") or "")
    if storage != "mcap":
        raise EfficientEQAError(f"{folder} is a rosbag2 recording in {storage or 'unnamed'} "
                                "storage; only MCAP storage is read", fix=_convert_fix(folder))
    compression = str(info.get("compression_format") or "")
    if compression:
        raise EfficientEQAError(f"{folder} is compressed ({compression}, by "
                                f"{info.get('compression_mode') or 'file'}); it is not read",
                                fix=f"{_convert_fix(folder)} (a copy without compression)")
    names = info.get("relative_file_paths")
    if (not isinstance(names, list) or not names
            or not all(isinstance(n, str) and n for n in names)):
        raise EfficientEQAError(f"{metadata} lists no files (relative_file_paths)",
                                fix=FIX_METADATA)
    return [_inside(folder, metadata, name) for name in names]


def _inside(folder: Path, metadata: Path, name: str) -> Path:
    """A listed file: relative to the folder (or, as early rosbag2 wrote them, to the folder
    above, starting with the folder's own name), and inside it."""
    file = folder / name
    parts = Path(name).parts
    if not file.exists() and len(parts) > 1 and parts[0] == folder.name:
        file = folder.parent / name
    root = folder.resolve()
    try:
        inside = file.resolve().is_relative_to(root)
    except (OSError, RuntimeError):  # a link loop
        inside = False
    if not inside:
        raise EfficientEQAError(f"{metadata} lists {name!r}, outside the bag folder",
                                fix=FIX_METADATA)
    if not file.is_file():
        raise EfficientEQAError(f"{metadata} lists {name}, which is missing",
                                fix="copy the whole bag folder, every file it lists")
    return file


# -- writing ------------------------------------------------------------------------------
@dataclass
class BagFile:
    """What the metadata says of one written .mcap file: its name in the folder, its messages'
    count per topic and their first and last log times (nanoseconds)."""

    name: str
    counts: dict[str, int]
    first_ns: int
    last_ns: int


def metadata_yaml(file: BagFile, types: Mapping[str, str],
                  qos: Mapping[str, str] | None = None) -> str:
    """``metadata.yaml`` of a bag of one file, as rosbag2 writes it (version 5): ``types`` maps
    each topic written to its ROS 2 type; ``qos`` a topic's offered QoS text, ``OFFERED_QOS``
    where not given. Written by hand, not by a YAML library: it is a fixed layout."""
    total = sum(file.counts.values())
    start = file.first_ns if total else 0
    duration = file.last_ns - file.first_ns if total else 0
    lines = ["rosbag2_bagfile_information:", f"  version: {METADATA_VERSION}",
             "  storage_identifier: mcap", "  duration:", f"    nanoseconds: {duration}",
             "  starting_time:", f"    nanoseconds_since_epoch: {start}",
             f"  message_count: {total}", "  topics_with_message_count:"]
    for topic in sorted(types):
        lines += ["    - topic_metadata:", f"        name: {topic}",
                  f"        type: {types[topic]}", "        serialization_format: cdr",
                  f"        offered_qos_profiles: {_quoted((qos or {}).get(topic, OFFERED_QOS))}",
                  f"      message_count: {file.counts.get(topic, 0)}"]
    lines += ['  compression_format: ""', '  compression_mode: ""', "  relative_file_paths:",
              f"    - {file.name}", "  files:", f"    - path: {file.name}", "      starting_time:",
              f"        nanoseconds_since_epoch: {start}", "      duration:",
              f"        nanoseconds: {duration}", f"      message_count: {total}"]
    return "\n".join(lines) + "\n"


def _quoted(text: str) -> str:
    """A YAML double-quoted scalar of ``text`` (newlines as \\n)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def bag_file_name(folder: Path, index: int = 0) -> str:
    """The name rosbag2 gives a bag's ``index``-th file: ``walk_0.mcap`` in ``walk/``."""
    return f"{folder.resolve().name}_{index}.mcap"
