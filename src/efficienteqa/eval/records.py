"""An evaluation run on disk: ``run.json`` (what was run) and ``episodes.jsonl`` (one line per
finished episode).

Only the driver process writes, one whole line per ``os.write`` on a file opened for appending,
flushed to disk before the next episode is handed out. A run killed mid-write leaves at most one
torn last line: readers skip it (and say so), and the next writer starts on a fresh line. Lines
are keyed by the episode id; a later line for the same id (a retried failure) replaces the
earlier one, so nothing is ever counted twice.

``run.json`` carries its format (``RUN_FORMAT``). Readers see every run in the current format:
``upgrade`` reads an older one as what it meant (DESIGN 6), so it resumes with the command
that made it and keeps its identity and its table label.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from efficienteqa.errors import EfficientEQAError
from efficienteqa.mapping.extent import MAP_SIZE_M
from efficienteqa.records import run_lock, write_json  # noqa: F401 - run_lock: imported from here too
from efficienteqa.redact import redacted
from efficienteqa.stop.rules import StopConfig, z_th_acts

RUN_FILE = "run.json"
EPISODES_FILE = "episodes.jsonl"
# What must be equal for a resumed run to continue an earlier one.
RUN_IDENTITY = ("method", "dataset", "closed_set", "config", "stack", "judge", "judge_mode")
# Also compared where the earlier run recorded them: which houses and simulator the scenes are
# (runs recorded before these keys existed resume as before).
SCENE_IDENTITY = ("assets", "env", "hm3d_root", "noise")
TRANSPORT = ("timeout_s", "retries")  # stack settings that are not part of a run's identity
# run.json's format. 1 (no "format" key): settings whose default was decided elsewhere were
# recorded as None, and settings added later were missing. 2: every setting is recorded as the
# value the run used, and the run names the configuration it started from ("preset", with
# what that alone set, "preset_config"). 3: the agent's settings are the configuration tree's
# sections ("explore", "stop" with its gate, "answer"), where 1 and 2 held them flat beside a
# nested "stop" (``nest_config``). 4: the agent's map lies around the start
# (``explore.map_extent`` "start"); earlier runs mapped the simulated scene's box ("scene").
# 5: the whole configuration tree the run was made from ("run", as ``efficienteqa config``
# prints it), beside the keys above, which stay the run's identity and labels.
RUN_FORMAT = 5
# Settings added with a format, by section, and what a run of an earlier format ran with (the
# size of a map around the start does not act on a map of the scene's box).
ADDED_IN_FORMAT_4 = {("explore", "map_extent"): "scene", ("explore", "map_size_m"): MAP_SIZE_M}
# What a format-1 run's None (or a run recorded before the setting existed) meant, by
# AgentConfig field: written out, not read from today's defaults, since a later default does
# not change what an old run ran with.
FORMAT_1_NONE = {"refusal_retries": 3, "stop_clearance_m": 0.45, "answer_every_step": False,
                 "answer_probability": "product", "token_answer": "short"}
# Settings added while format 1 was written, and what a run that did not record them ran with:
# no answerability gate, no steering by the question's target (DESIGN 9).
FORMAT_1_MISSING = {"gate": "none", "steering": "none"}
# AgentConfig settings added after format 2, in any format: what a run that did not record them
# ran with (the question read by rules, its words matched as words, no stop on a final gate
# verdict; DESIGN 9).
ADDED_SETTINGS = {"reading": "rules", "matching": "words", "gate_final": False,
                  "step_weight": "relevancy"}
# Settings of the configuration tree added while format 4 is written, by section, and what a
# run that did not record them ran with: a count question's group merged across views by
# position (before the instance map, DESIGN 9); the relevancy reading the question as asked
# (before it could read it in the perception's words).
ADDED_NESTED = {("stop", "count_from"): "views", ("stop", "question_words"): "asked"}
# The stack's None (or a setting it did not record yet): each call's own temperature, 0 for
# every call of a run; the relevancy model on the GPU torch sees, else the CPU; no download of
# its weights; images at 512 px, as JPEG for openai: servers and PNG for the local one ("auto").
FORMAT_1_STACK_NONE = {"temperature": 0.0, "device": "auto", "allow_download": False,
                       "image_max_side": 512, "image_format": "auto"}


@dataclass
class Episodes:
    """The episodes of a run as read back: the last line of each id, in file order."""

    by_id: dict[str, dict[str, Any]] = field(default_factory=dict)
    torn: int = 0  # unreadable lines (a run killed mid-write, or not an episode's line)
    foreign: int = 0  # lines of another method or of none of the run's questions (``read_run``)

    @property
    def done(self) -> set[str]:
        return {k for k, v in self.by_id.items() if v.get("status") == "done"}

    def rows(self) -> list[dict[str, Any]]:
        return list(self.by_id.values())


def read_episodes(path: Path) -> Episodes:
    out = Episodes()
    if not path.exists():
        return out
    try:
        f = path.open("rb")
    except OSError as error:  # a folder of that name, a file this user may not read
        raise EfficientEQAError(f"cannot read {path}: {error.strerror or error}",
                                fix="restore it, or use another --out folder") from None
    with f:
        for raw in f:
            try:
                row = json.loads(raw)
            except ValueError:
                row = None
            key = row.get("id") if isinstance(row, dict) else None
            if not isinstance(key, str):  # torn, or not one episode's line
                out.torn += 1
                continue
            out.by_id.pop(key, None)  # the later line wins and moves to the end
            out.by_id[key] = row
    return out


def _open_for_append(path: Path) -> int:
    return os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)


def _unwritable(path: Path, error: OSError, row: dict[str, Any]) -> EfficientEQAError:
    """One line for a line that could not be written: which episode's result that was, and
    that the same command runs it again (it is not in the file, so it is not done)."""
    key = row.get("id")
    return EfficientEQAError(
        f"cannot write {path}: {error.strerror or error}"
        + (f"; the result of episode {key} is not saved" if isinstance(key, str) else ""),
        fix="free disk space or make the file writable, or use another --out folder; the "
            "same command resumes the run")


def append_episode(path: Path, row: dict[str, Any]) -> None:
    """Append one line atomically enough for one writer: a single ``write`` of the whole line,
    then ``fsync``. A file that ends mid-line (a killed writer) gets a newline first. A file
    that cannot be opened or written (a full disk, a file made read-only) is one line naming
    the episode whose line is lost. Passwords in URLs are written as ``***`` (``redact``)."""
    data = (json.dumps(redacted(row), allow_nan=False, separators=(",", ":")) + "\n").encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = _open_for_append(path)
    except OSError as error:
        raise _unwritable(path, error, row) from None
    try:
        size = os.fstat(fd).st_size
        if size:
            with path.open("rb") as f:
                f.seek(size - 1)
                if f.read(1) != b"\n":
                    data = b"\n" + data
        while data:  # a short write (a full disk) must not leave a short line unsaid
            data = data[os.write(fd, data):]
        os.fsync(fd)
    except OSError as error:
        raise _unwritable(path, error, row) from None
    finally:
        os.close(fd)


def check_appendable(path: Path) -> None:
    """Before any episode runs: a run's ``episodes.jsonl`` that exists must take more lines (a
    file made read-only or immutable lost the result of the first episode run after it)."""
    if not path.exists():
        return  # made by the first line, in a folder ``check_writable`` tried
    try:
        os.close(_open_for_append(path))
    except OSError as error:
        raise EfficientEQAError(f"cannot write {path}: {error.strerror or error}",
                                fix="make it writable, or use another --out folder") from None


def compact_episodes(path: Path) -> int:
    """Rewrite ``path`` with one line per episode (the line that wins when read) and without torn
    lines: a temporary file replaces it in one ``os.replace``, so a crash leaves either file whole.
    Returns the lines kept. Used after a regrade, which appends a line for every episode."""
    episodes = read_episodes(path)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w") as f:
        for row in episodes.rows():
            f.write(json.dumps(redacted(row), allow_nan=False, separators=(",", ":")) + "\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return len(episodes.by_id)


def check_resumable(out: Path, manifest: dict[str, Any]) -> dict[str, Any] | None:
    """The run recorded in ``out`` (its run.json as written), which ``manifest`` may continue,
    or None when ``out`` holds no run yet. A folder holding a different run (another method,
    dataset, configuration or back-end), or episodes without their run.json, is refused rather
    than mixed. Reads only: eval calls it before building the dataset's houses too."""
    run_file = out / RUN_FILE
    episodes = read_episodes(out / EPISODES_FILE)  # one that cannot be read is said first
    if not run_file.exists():
        if episodes.by_id:
            raise EfficientEQAError(f"{out} holds episodes but no {RUN_FILE}, so what ran them "
                                    "is unknown", fix="use a new --out folder")
        return None
    recorded = _read_manifest(run_file)
    earlier = upgrade(recorded)
    differs = [k for k in RUN_IDENTITY if _identity(k, earlier) != _identity(k, manifest)]
    differs += [k for k in SCENE_IDENTITY if k in earlier and earlier[k] != manifest.get(k)]
    if differs:
        changed = _changes(differs, earlier, manifest)
        raise EfficientEQAError(
            f"{out} holds a run with another {', '.join(differs)}"
            + (f" ({changed})" if changed else ""),
            fix="use a new --out folder for a new configuration, or the run's own settings")
    return recorded


def open_run(out: Path, manifest: dict[str, Any]) -> Episodes:
    """Start a run in ``out`` or continue the one there (``check_resumable``)."""
    run_file = out / RUN_FILE
    recorded = check_resumable(out, manifest)
    if recorded is not None:
        _add_questions(run_file, recorded, manifest.get("question_ids"))
    else:
        write_json(run_file, manifest)
    episodes = read_episodes(out / EPISODES_FILE)
    check_appendable(out / EPISODES_FILE)
    return episodes


def _add_questions(run_file: Path, recorded: dict[str, Any], ids: Any) -> None:
    """A resumed run's question set grows by the questions of this command (a larger --eval.limit):
    ``run.json`` lists every question any command of the run asked (``question_ids``), and
    their number (``questions``), so a report counts exactly these. A run recorded before
    runs listed their questions keeps its run.json as it is: which questions its earlier
    commands asked is not known."""
    listed = recorded.get("question_ids")
    if not isinstance(listed, list) or not isinstance(ids, list):
        return
    union = list(dict.fromkeys([*listed, *ids]))
    if len(union) != len(listed):
        write_json(run_file, {**recorded, "question_ids": union, "questions": len(union)})


def _read_manifest(run_file: Path) -> dict[str, Any]:
    try:
        manifest = json.loads(run_file.read_text())
    except (ValueError, UnicodeDecodeError):
        manifest = None
    except OSError as error:  # a folder of that name, a file this user may not read
        raise EfficientEQAError(f"cannot read {run_file}: {error.strerror or error}",
                                fix="restore it, or use another --out folder") from None
    if not isinstance(manifest, dict):
        raise EfficientEQAError(f"{run_file} is not a run's JSON object",
                                fix="restore it, or use another --out folder") from None
    return manifest


def _nested(config: Mapping[str, Any]) -> bool:
    """Whether an agent configuration is recorded as the tree's sections."""
    from efficienteqa.agent import AgentConfig

    sections = {f.name for f in fields(AgentConfig)}
    return all(key in sections and isinstance(value, Mapping) for key, value in config.items())


def nest_config(config: Mapping[str, Any]) -> dict[str, Any]:
    """An agent configuration recorded flat (formats 1 and 2: ``top_k``, ``gate``... beside a
    nested ``stop``) as the tree's sections, each flat name in the section that holds it today
    (``knobs.flat_names``); a configuration already in sections is returned as it is."""
    from efficienteqa.agent import AgentConfig
    from efficienteqa.config.knobs import flat_names

    if _nested(config):
        return dict(config)
    sections = {f.name for f in fields(AgentConfig)}
    index = flat_names(AgentConfig)
    out: dict[str, Any] = {s: {} for s in sections}
    for key, value in config.items():  # in order: a section's values win over flat ones before
        if key in sections and isinstance(value, Mapping):
            out[key].update(value)
        elif key in index:
            section, name = index[key]
            out[section][name] = value
        else:  # a setting no longer known keeps its place, so the run still differs from others
            out.setdefault("retired", {})[key] = value
    return out


def upgrade(manifest: dict[str, Any]) -> dict[str, Any]:
    """``manifest`` in the current format (``RUN_FORMAT``); a format-1 run's None settings, and
    the ones it did not record yet, become the values it ran with (``FORMAT_1_*``). A run
    without ``preset_config`` (format 1) is labelled against today's defaults. The stack's
    Nones are read so in any format: format 2 was first written with None for the relevancy
    device, the download switch and the image settings, which meant what they mean in format 1.
    A flat agent configuration (formats 1 and 2) becomes the tree's sections (``nest_config``)."""
    out = dict(manifest)
    stack = out.get("stack")
    if isinstance(stack, dict):
        if "image_format" not in stack and str(stack.get("vlm", "")).startswith("openai:"):
            stack = {**stack, "image_format": "png"}  # recorded before JPEG became openai:'s
        if "sightings" not in stack and stack.get("perception") != "rgb":
            # recorded before the source was an option: the perception's own, which "auto"
            # is for these (an rgb run had none: it stays unlike any run of today)
            stack = {**stack, "sightings": "auto"}
        out["stack"] = {**stack, **{k: v for k, v in FORMAT_1_STACK_NONE.items()
                                    if stack.get(k) is None}}
    keys = [k for k in ("config", "method_config", "preset_config")
            if isinstance(out.get(k), dict) and not _nested(out[k])]
    if manifest.get("format", 1) < RUN_FORMAT:
        for key in keys:
            out[key] = {**ADDED_SETTINGS, **out[key]}
        if manifest.get("format", 1) < 2:
            for key in keys:
                if key != "preset_config":
                    config = {**FORMAT_1_MISSING, **out[key]}
                    config.update({k: v for k, v in FORMAT_1_NONE.items()
                                   if config.get(k) is None})
                    out[key] = config
    for key in keys:
        out[key] = nest_config(out[key])
    filled: set[str] = set()
    for key in ("config", "method_config", "preset_config"):
        if isinstance(out.get(key), dict):
            for (section, name), value in ADDED_NESTED.items():
                if isinstance(out[key].get(section), dict) and name not in out[key][section]:
                    out[key] = {**out[key], section: {**out[key][section], name: value}}
                    filled.add(name)
    for key in ("config", "method_config", "preset_config"):
        stop = out.get(key, {}).get("stop") if isinstance(out.get(key), dict) else None
        if isinstance(stop, dict) and "z_gated" not in stop and z_th_acts(str(stop.get("gate"))):
            # recorded before z_gated existed, with a gate that leaves the stop to Z_th: any
            # value acts alike, so it reads as today's default (which that gate ignores)
            out[key] = {**out[key], "stop": {**stop, "z_gated": StopConfig().z_gated}}
            filled.add("z_gated")
    if manifest.get("format", 1) < 4:
        filled |= {added for _, added in ADDED_IN_FORMAT_4}
        for key in ("config", "method_config", "preset_config"):
            if isinstance(out.get(key), dict):
                out[key] = {**out[key]}
                for (section, added), default in ADDED_IN_FORMAT_4.items():
                    out[key][section] = {added: default, **out[key].get(section, {})}
    if filled:  # noted, so a label does not name them as changes
        out["unrecorded"] = sorted(filled)
    out["format"] = RUN_FORMAT
    return out


def _changes(keys: list[str], earlier: dict[str, Any], now: dict[str, Any],
             limit: int = 4) -> str:
    """The settings that differ, as "name: was -> now" (a nested setting by its path within the
    key, e.g. the stack's vlm when the server's URL changed, or the config's stop.gate);
    passwords in URLs are left out."""
    from efficienteqa.config.knobs import flatten

    said: list[str] = []
    for key in keys:
        before, after = _identity(key, earlier), _identity(key, now)
        if isinstance(before, dict) and isinstance(after, dict):
            was, now_ = flatten(before), flatten(after)
            said += [f"{'.'.join(k)}: {_shown(was.get(k))} -> {_shown(now_.get(k))}"
                     for k in sorted(set(was) | set(now_)) if was.get(k) != now_.get(k)]
        else:
            said.append(f"{key}: {_shown(before)} -> {_shown(after)}")
    return "; ".join(said[:limit]) + ("; ..." if len(said) > limit else "")


def _shown(value: Any) -> str:
    """A setting as an error line shows it: short, and without a URL's user and password."""
    text = re.sub(r"//[^/@\s]+@", "//", json.dumps(value) if not isinstance(value, str) else value)
    return text if len(text) <= 80 else text[:77] + "..."


def _identity(key: str, manifest: dict[str, Any]) -> Any:
    """What of ``manifest[key]`` identifies the run: a model server's timeout and retries change
    how long a call may take, not what it answers, so a run resumes with others; the judge's
    mode counts only where there is a judge. A URL's password is not recorded (``redact``), so
    it is not compared: the run resumes with the command that made it."""
    if key == "judge_mode" and manifest.get("judge") is None:
        return None
    value = _set(redacted(manifest.get(key)))
    if key == "stack" and isinstance(value, dict):
        value = {k: v for k, v in value.items() if k not in TRANSPORT}
    return value


def _set(value: Any) -> Any:
    """``value`` without None entries or empty dicts at any depth (a setting that is None in
    both runs, such as ``max_steps`` or a server option left to the back-end, is the same in
    both; so are no overrides and overrides not recorded yet)."""
    if isinstance(value, dict):
        kept = {k: _set(v) for k, v in value.items() if v is not None}
        return {k: v for k, v in kept.items() if v != {}}
    return value


def read_run(out: Path) -> tuple[dict[str, Any], Episodes]:
    """A run folder for reports: its manifest and its episodes, less the lines that are not
    the run's (``Episodes.foreign``): another method's, and, where run.json lists the run's
    questions (``question_ids``), those of no question it asked, which a report would
    otherwise count as episodes ("9 of 8") and in its accuracy."""
    run_file = out / RUN_FILE
    if not run_file.exists():
        raise EfficientEQAError(f"{out} is not an evaluation run (no {RUN_FILE})",
                                fix="pass folders written by `efficienteqa eval --out`")
    manifest = upgrade(_read_manifest(run_file))
    episodes = read_episodes(out / EPISODES_FILE)
    ids = manifest.get("question_ids")
    asked = {i for i in ids if isinstance(i, str)} if isinstance(ids, list) else None
    for key, row in list(episodes.by_id.items()):
        if (row.get("method") not in (None, manifest.get("method"))
                or (asked is not None and key not in asked)):
            del episodes.by_id[key]
            episodes.foreign += 1
    return manifest, episodes
