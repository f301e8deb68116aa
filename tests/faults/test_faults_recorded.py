"""Fault trials R6.1-R6.21 and R6.29-R6.31 (FAULT-TRIALS-2): recorded walks, as MCAP files and
as folders, and ``--scene ros2``, handed over damaged as a user may hand them over.

Two valid walks are made once for the module (``walks``): ``ask --record`` in synthetic house 3
(an .mcap file), then that walk replayed with ``--record`` into a folder; both in a folder whose
name has a space. Each trial damages a copy: MCAP copies are rewritten message by message
(``rewrite``: each message decoded with mcap_ros2, one field changed, written again with its own
schema), folder copies are edited in place. A bad file must be one ``error:`` line naming the
file (and its line, or its topic and message); one that can be checked when the walk is opened
is refused then, before any model call (``refused``).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from clirun import Result
from faults.harness import KEY, SECRETS, files_holding, one_error_line, ran, trial
from vlm_server import servers

pytest.importorskip("mcap_ros2")

QUESTION = "What colour is the bed?"
FRAMES = 3
COLOUR = "/camera/color/image_raw"
DEPTH = "/camera/aligned_depth_to_color/image_raw"
INFO = "/camera/color/camera_info"
LABELS = "/efficienteqa/labels"


@dataclass(frozen=True)
class Walks:
    mcap: Path  # walks dir/walk a.mcap
    folder: Path  # walks dir/walk b
    backends: tuple[str, ...]  # the module's test server
    server: Any


@pytest.fixture(scope="module")
def walks(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Walks]:
    """The valid walks (R6.1), in a folder with a space in its name (R6.18), made by the
    command as a user makes them."""
    from efficienteqa.cli import main

    root = tmp_path_factory.mktemp("recorded") / "walks dir"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("EFFICIENTEQA_", "RAY_"))}
    env.update(OPENAI_API_KEY=KEY, EFFICIENTEQA_CACHE=str(root / "cache"), COLUMNS="300")
    with servers() as start, pytest.MonkeyPatch.context() as patch:
        server = start()
        backends = ("--backends.vlm", f"openai:fake@{server.base_url}", "--backends.api-key-env",
                    "OPENAI_API_KEY", "--backends.relevancy", "overlap", "--explore.matching",
                    "words", "--backends.no-cache")
        for name in set(os.environ) - set(env):
            patch.delenv(name)
        for name, value in env.items():
            patch.setenv(name, value)
        walks = Walks(root / "walk a.mcap", root / "walk b", backends, server)
        for scene, record in (("synthetic:3", walks.mcap), (f"recorded:{walks.mcap}",
                                                              walks.folder)):
            patch.setattr("sys.argv", [
                "efficienteqa", "ask", QUESTION, "--scene", scene, "--scene.assets", "builtin",
                "--explore.max-steps", str(FRAMES), *backends, "--record", str(record),
                "--out", str(root / f"out {record.name}")])
            with pytest.raises(SystemExit) as done:
                main()
                raise SystemExit(0)
            assert done.value.code in (0, None) and record.exists()
        yield walks


def replay(cli: Callable[..., Result], walks: Walks, spec: str | Path, out: Path) -> Result:
    """``ask`` on the recording ``spec`` (a path, with options after "?")."""
    return cli("ask", QUESTION, "--scene", f"recorded:{spec}", *walks.backends, "--out", str(out))


def refused(cli: Callable[..., Result], walks: Walks, spec: str | Path, tmp_path: Path) -> str:
    """The one error line of replaying ``spec``, said when the walk was opened: no model call,
    no episode written."""
    calls = len(walks.server.requests)
    line = one_error_line(replay(cli, walks, spec, tmp_path / "out"))
    assert len(walks.server.requests) == calls, line
    assert not (tmp_path / "out" / "episode.json").exists(), line
    return line


def rewrite(walks: Walks, dst: Path, change: Callable[[str, int, Any], object]) -> Path:
    """A copy of the MCAP walk with every message decoded and handed to ``change(topic, n,
    msg)`` (``n``: its place on its topic, from 0), which may change it in place or return
    False to leave it out; written again with its own schema, in the same order."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from mcap_ros2.writer import Writer

    decoders, seen = DecoderFactory(), Counter[str]()
    with open(walks.mcap, "rb") as stream, open(dst, "wb") as out:
        writer, schemas = Writer(out), {}
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=True):
            msg = decoders.decoder_for(channel.message_encoding, schema)(message.data)
            n = seen[channel.topic]
            seen[channel.topic] += 1
            if change(channel.topic, n, msg) is False:
                continue
            if schema.name not in schemas:
                schemas[schema.name] = writer.register_msgdef(schema.name, schema.data.decode())
            writer.write_message(channel.topic, schemas[schema.name], msg,
                                 log_time=message.log_time, publish_time=message.publish_time)
        writer.finish()
    return dst


def stamps(msg: Any) -> list[Any]:
    """The header stamps of a message (a TF message's: each transform's)."""
    return [t.header.stamp for t in msg.transforms] if hasattr(msg, "transforms") else \
        [msg.header.stamp] if hasattr(msg, "header") else []


def folder_copy(walks: Walks, tmp_path: Path) -> Path:
    copy = tmp_path / "walk copy"
    shutil.copytree(walks.folder, copy)
    return copy


def poses(folder: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (folder / "poses.jsonl").read_text().splitlines()]


def write_poses(folder: Path, rows: list[Any]) -> None:
    (folder / "poses.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))


# ---------------------------------------------------------------- R6.1, R6.18: valid walks

@trial("R6.1", "R6.18")
def test_a_recorded_walk_replays_as_mcap_and_as_folder_with_spaces_in_its_paths(cli, walks,
                                                                                tmp_path):
    for spec, note, kind in ((walks.mcap, f"walk a.mcap: {FRAMES} frames of {FRAMES}; with the "
                                          "simulator's labels", "mcap"),
                             (walks.folder, f"walk b: {FRAMES} frames; with the simulator's "
                                            "labels", "folder")):
        out = tmp_path / f"re {spec.name}"
        said = ran(replay(cli, walks, spec, out))
        assert note in said and f"steps: {FRAMES} of {FRAMES}" in said
        episode = json.loads((out / "episode.json").read_text())
        assert episode["answer"] and episode["scene"] == f"recorded:{spec} ({kind})"
        assert episode["backends"]["environment"] == f"recorded ({kind})"  # not "recorded a.mcap"

    # The recordings themselves hold no secret (the per-test check reads only tmp_path).
    assert [f for s in SECRETS for f in files_holding(walks.mcap.parent, s)] == []


# ---------------------------------------------------------------- R6.2-R6.6: damaged bytes

def _zero(path: Path, data: bytes) -> None:
    path.write_bytes(b"")


def _random(path: Path, data: bytes) -> None:
    path.write_bytes(np.random.default_rng(6).bytes(200_000))


def _sparse(path: Path, data: bytes) -> None:
    with open(path, "wb") as out:
        out.truncate(3 << 30)  # 3 GB of zeros, not written


def _magic(path: Path, data: bytes) -> None:
    with open(path, "wb") as out:
        out.write(data[:8])  # the MCAP magic, then 1 GB of zeros
        out.truncate(1 << 30)


BYTES = {"zero": (_zero, "EndOfFile"), "random": (_random, "InvalidMagic"),
         "sparse": (_sparse, "as MCAP"), "magic": (_magic, "as MCAP"),
         "cut-100": (lambda p, d: p.write_bytes(d[:100]), "as MCAP"),
         "cut-half": (lambda p, d: p.write_bytes(d[:len(d) // 2]), "mcap recover"),
         "cut-20": (lambda p, d: p.write_bytes(d[:-20]), "as MCAP")}


@trial("R6.2", "R6.3", "R6.4", "R6.5")
@pytest.mark.parametrize("case", list(BYTES))
def test_an_mcap_that_is_no_mcap_is_one_line(cli, walks, tmp_path, case):
    damage, said = BYTES[case]
    path = tmp_path / f"{case}.mcap"
    damage(path, walks.mcap.read_bytes())
    try:
        line = refused(cli, walks, path, tmp_path)
    finally:
        path.unlink()  # not read whole by the secret check either
    assert f"cannot read {path} as MCAP" in line and said in line


@trial("R6.6")
def test_bytes_flipped_inside_a_chunk_are_read_or_one_line(cli, walks, tmp_path):
    """The chunk's CRC is not checked: flipped bytes that land in pixels are read as pixels."""
    data = bytearray(walks.mcap.read_bytes())
    at = len(data) // 2
    data[at:at + 64] = bytes(b ^ 0xFF for b in data[at:at + 64])
    path = tmp_path / "flipped.mcap"
    path.write_bytes(bytes(data))
    result = replay(cli, walks, path, tmp_path / "out")
    if result.returncode:
        assert "as MCAP" in one_error_line(result)
    else:
        assert f"{FRAMES} frames of {FRAMES}" in ran(result)


# ---------------------------------------------------------------- R6.7-R6.10: topics missing

DROPS = {  # which topics are left out -> what is said
    "no images": ({COLOUR, DEPTH, "/efficienteqa/instance"}, "has no colour topic"),
    "depth only": ({COLOUR}, "has no colour topic"),
    "labels only": ({COLOUR, DEPTH, INFO, "/tf", "/efficienteqa/instance"},
                    "has no colour topic"),
    "no messages": (None, "has no colour topic"),
    "no camera_info": ({INFO}, "has no camera_info topic"),
    "no tf": ({"/tf"}, "no TF path from 'map'"),
    "no depth": ({DEPTH}, "has no depth topic"),
}


@trial("R6.7", "R6.8", "R6.9", "R6.10")
@pytest.mark.parametrize("case", list(DROPS))
def test_an_mcap_without_a_topic_it_needs_is_one_line(cli, walks, tmp_path, case):
    drop, said = DROPS[case]
    path = rewrite(walks, tmp_path / "w.mcap",
                   lambda topic, n, msg: drop is not None and topic not in drop)
    assert said in refused(cli, walks, path, tmp_path)


# ---------------------------------------------------------------- R6.11, R6.12: stamps

def _frame_stamps(walks: Walks) -> list[int]:
    """The stamps of the walk's frames (every header of a frame has its frame's)."""
    from efficienteqa.envs.recorded import open_recording

    walk = open_recording(str(walks.mcap))
    ns = [int(f.stamp) for f in walk.source._frames]
    walk.close()
    return ns


def _reverse(walks: Walks) -> Callable[[str, int, Any], None]:
    """Every header stamp mirrored in the walk's span: the last frame first."""
    ns = _frame_stamps(walks)

    def change(topic: str, n: int, msg: Any) -> None:
        for stamp in stamps(msg):
            stamp.sec, stamp.nanosec = divmod(ns[0] + ns[-1] - (stamp.sec * 10**9 + stamp.nanosec),
                                              10**9)

    return change


def _swap_pairs(walks: Walks) -> Callable[[str, int, Any], None]:
    """Colour frames 0 and 1 take each other's stamps."""
    ns = _frame_stamps(walks)

    def change(topic: str, n: int, msg: Any) -> None:
        if topic == COLOUR and n < 2:
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns[1 - n], 10**9)

    return change


@trial("R6.11")
@pytest.mark.parametrize("case", ["reversed", "pairs swapped"])
def test_stamps_out_of_order_are_read_in_stamp_order(cli, walks, tmp_path, case):
    path = rewrite(walks, tmp_path / "w.mcap",
                   (_reverse if case == "reversed" else _swap_pairs)(walks))
    said = ran(replay(cli, walks, path, tmp_path / "out"))
    assert f"{FRAMES} frames of {FRAMES}" in said and "warning" not in said


def _same_colour_stamp(topic: str, n: int, msg: Any) -> None:
    if topic == COLOUR:
        msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_000, 0


def _all_zero(topic: str, n: int, msg: Any) -> None:
    for stamp in stamps(msg):
        stamp.sec, stamp.nanosec = 0, 0


@trial("R6.12")
@pytest.mark.parametrize("change", [_same_colour_stamp, _all_zero], ids=["same", "zero"])
def test_a_walk_whose_frames_share_one_stamp_is_refused(cli, walks, tmp_path, change):
    """Every frame would get frame 0's pose (and depth): the walk cannot be placed."""
    path = rewrite(walks, tmp_path / "w.mcap", change)
    line = refused(cli, walks, path, tmp_path)
    assert f"w.mcap: all {FRAMES} colour frames of {COLOUR} have the stamp" in line
    assert "cannot be placed" in line and "mcap recover" not in line


@trial("R6.12")
def test_frames_that_repeat_a_stamp_are_read_with_a_warning(walks, tmp_path):
    from efficienteqa.envs.recorded import open_recording

    first: list[Any] = []

    def change(topic: str, n: int, msg: Any) -> None:
        if topic == COLOUR and n == 0:
            first.append(msg.header.stamp)
        elif topic == COLOUR and n == 1:
            msg.header.stamp = first[0]

    walk = open_recording(str(rewrite(walks, tmp_path / "w.mcap", change)))
    assert walk.length == FRAMES
    assert walk.note.endswith("; warning: 1 colour frames repeat another's stamp, so they get "
                              "its pose and depth")
    walk.close()


# ---------------------------------------------------------------- R6.13-R6.17: bad fields

def _field(topic_of: str, n_of: int, set_it: Callable[[Any], None]
           ) -> Callable[[str, int, Any], None]:
    def change(topic: str, n: int, msg: Any) -> None:
        if topic == topic_of and n == n_of:
            set_it(msg)
    return change


def _rotation(msg: Any) -> None:
    r = msg.transforms[0].transform.rotation
    r.x = r.y = r.z = r.w = 0.0


def _translation(msg: Any) -> None:
    msg.transforms[0].transform.translation.y = math.nan


def _k(msg: Any) -> None:
    msg.k = [*msg.k[:2], math.nan, *msg.k[3:]]


def _short(msg: Any) -> None:
    msg.data = msg.data[:len(msg.data) // 2]


def _huge(msg: Any) -> None:
    msg.width = msg.height = 100_000
    msg.step = 3 * 100_000


def _mono8(msg: Any) -> None:
    msg.encoding = "mono8"


def _labels(text: str) -> Callable[[Any], None]:
    def set_it(msg: Any) -> None:
        msg.data = text
    return set_it


FIELDS = {  # trial, the message changed, how -> what the one line says (after "w.mcap: ")
    "zero quaternion": ("R6.13", "/tf", 1, _rotation,
                        "/tf message 2: the transform 'map' -> 'camera_color_optical_frame' "
                        "has the rotation [0.0, 0.0, 0.0, 0.0] (no quaternion)"),
    "nan translation": ("R6.14", "/tf", 1, _translation, "/tf message 2: the transform 'map' -> "
                        "'camera_color_optical_frame' has the translation ["),
    "nan K": ("R6.14", INFO, 2, _k, f"{INFO} message 3: camera_info K is not finite"),
    "short data": ("R6.15", COLOUR, 1, _short,
                   f"{COLOUR} message 2: a 640x480 rgb8 image needs 480 rows of 1920 bytes, but "
                   "step is 1920 and the data holds 460800 bytes (height x step: 921600)"),
    "huge size": ("R6.15", COLOUR, 2, _huge, f"{COLOUR} message 3: a 100000x100000 rgb8 image "
                  "needs 100000 rows of 300000 bytes"),
    "mono8": ("R6.16", COLOUR, 2, _mono8, f"{COLOUR} message 3: colour encoding 'mono8' is not "
              "read"),
    "labels not JSON": ("R6.17", LABELS, 0, _labels("{nope"), f"{LABELS} of w.mcap is not JSON"),
    "labels nested too deep": ("R6.17", LABELS, 0, _labels("[" * 100_000),
                               f"{LABELS} of w.mcap is not JSON"),
    "labels shape": ("R6.17", LABELS, 0, _labels("[1, 2]"), "cannot read the object labels of "
                     f"w.mcap ({LABELS})"),
}


@trial("R6.13", "R6.14", "R6.15", "R6.16", "R6.17")
@pytest.mark.parametrize("case", list(FIELDS))
def test_a_bad_field_in_an_mcap_is_one_line_naming_its_message(cli, walks, tmp_path, case):
    _, topic, n, set_it, said = FIELDS[case]
    path = rewrite(walks, tmp_path / "w.mcap", _field(topic, n, set_it))
    line = refused(cli, walks, path, tmp_path)
    assert said in line and "mcap recover" not in line and "as MCAP" not in line


# ---------------------------------------------------------------- R6.13, R6.19: options

OPTIONS = {"world=nosuch": "no TF path from 'nosuch'", "foo=1": "unknown recording option 'foo=1'",
           "depth_tolerance_ms=nan": "depth_tolerance_ms='nan' is not a duration",
           "depth_tolerance_ms=1e400": "depth_tolerance_ms='1e400' is not a duration: it must be "
                                       "a finite number of milliseconds",
           "tf_tolerance_ms=-1": "tf_tolerance_ms='-1' is not a duration",
           "colour=/nope": "has no sensor_msgs/msg/Image topic '/nope'"}


@trial("R6.13", "R6.19")
@pytest.mark.parametrize("option", list(OPTIONS))
def test_a_bad_recording_option_is_one_line(cli, walks, tmp_path, option):
    line = refused(cli, walks, f"{walks.mcap}?{option}", tmp_path)
    assert OPTIONS[option] in line and "mcap recover" not in line


@trial("R6.19")
def test_an_option_on_a_folder_is_refused_and_zero_tolerances_read_exact_stamps(cli, walks,
                                                                               tmp_path):
    from efficienteqa.envs.recorded import open_recording

    assert "options world are for MCAP recordings" in refused(cli, walks, f"{walks.folder}?world=x",
                                                         tmp_path)
    walk = open_recording(f"{walks.mcap}?tf_tolerance_ms=0&depth_tolerance_ms=0")
    assert walk.length == FRAMES  # the recorder stamps every topic of a frame alike
    walk.close()


# ---------------------------------------------------------------- R6.20, R6.21: folder walks

def _line(n: int, text: str | bytes) -> Callable[[Path], None]:
    """Line ``n`` (from 1) of poses.jsonl replaced by ``text``."""
    def damage(folder: Path) -> None:
        lines = (folder / "poses.jsonl").read_bytes().splitlines()
        lines[n - 1] = text if isinstance(text, bytes) else text.encode()
        (folder / "poses.jsonl").write_bytes(b"\n".join(lines) + b"\n")
    return damage


def _row(n: int, **values: Any) -> Callable[[Path], None]:
    """Row ``n`` (from 1) of poses.jsonl with ``values`` set (None: the key left out)."""
    def damage(folder: Path) -> None:
        rows = poses(folder)
        rows[n - 1].update(values)
        rows[n - 1] = {k: v for k, v in rows[n - 1].items() if v is not None}
        write_poses(folder, rows)
    return damage


def _file(name: str, make: Callable[[Path], None]) -> Callable[[Path], None]:
    return lambda folder: make(folder / name)


def _depth_8bit(folder: Path) -> None:
    from PIL import Image

    Image.fromarray(np.zeros((480, 640), np.uint8)).save(folder / "depth" / "8bit.png")
    _row(2, depth="depth/8bit.png")(folder)


def _instance(make: Callable[[Path], None], suffix: str) -> Callable[[Path], None]:
    """Frame 1's instance ids replaced by the file ``make`` writes, as instance/000000.SUFFIX."""
    def damage(folder: Path) -> None:
        for old in (folder / "instance").glob("000000.*"):
            old.unlink()
        make(folder / "instance" / f"000000.{suffix}")
        _row(1, instance=f"instance/000000.{suffix}")(folder)
    return damage


def _png(array: Any) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        from PIL import Image

        Image.fromarray(array).save(path)
    return make


def _npy(array: Any) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        np.save(path, array, allow_pickle=True)
    return make


def _cut(fraction: float) -> Callable[[Path], None]:
    def make(path: Path) -> None:
        data = path.read_bytes()
        path.write_bytes(data[:int(len(data) * fraction)])
    return make


def _leaves(folder: Path) -> None:
    outside = folder.parent / "outside.png"
    shutil.copy(folder / "rgb" / "000000.png", outside)
    _row(1, rgb="../outside.png")(folder)


def _link_out(folder: Path) -> None:
    outside = folder.parent / "outside.png"
    shutil.copy(folder / "rgb" / "000001.png", outside)
    (folder / "rgb" / "link.png").symlink_to(outside)
    _row(2, rgb="rgb/link.png")(folder)


L = "poses.jsonl line"
FOLDERS = {  # trial, damage -> what the one line says
    # R6.20 (held before; the 8-bit depth is now found when the walk is opened)
    "garbage line": ("R6.20", _line(2, "{nope"), f"cannot read {{}}/{L} 2: JSONDecodeError"),
    "list line": ("R6.20", _line(2, "[1, 2]"), f"{L} 2: TypeError"),
    "no rotation": ("R6.20", _row(1, cam_to_world=np.diag([2.0, 1, 1, 1]).tolist()),
                    f"{L} 1: cam_to_world's 3x3 part is not a rotation"),
    "fx NaN": ("R6.20", _row(3, fx="NaN"), f"{L} 3: fx, fy, cx, cy must be finite"),
    "empty": ("R6.20", lambda f: (f / "poses.jsonl").write_text(""), "poses.jsonl lists no frame"),
    "no rgb": ("R6.20", _row(2, rgb=None), f"{L} 2 names no rgb file"),
    "missing depth": ("R6.20", lambda f: (f / "depth" / "000001.npy").unlink(),
                      f"{L} 2: depth file depth/000001.npy is missing"),
    "labels shape": ("R6.20", lambda f: (f / "labels.json").write_text("[1]"),
                     "cannot read the object labels of {}/labels.json"),
    "8-bit depth": ("R6.20", _depth_8bit, f"{L} 2: cannot read depth file depth/8bit.png: it is "
                                          "a L image, not 16-bit"),
    # R6.21
    "corrupt first png": ("R6.21", _file("rgb/000000.png", lambda p: p.write_bytes(
        b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)),
        f"{L} 1: cannot read rgb file rgb/000000.png: cannot identify image file"),
    "npy garbage": ("R6.21", _file("depth/000001.npy", lambda p: p.write_bytes(
        b"\x93NUMPY\x09\x00garbage" * 10)), f"{L} 2: cannot read depth file depth/000001.npy: "),
    "npy 1-D": ("R6.21", _file("depth/000001.npy", _npy(np.zeros(5, np.float32))),
                f"{L} 2: cannot read depth file depth/000001.npy: its array is 1-D, not 2-D"),
    "npy objects": ("R6.21", _file("depth/000001.npy", _npy(np.array([{"a": 1}, None]))),
                    f"{L} 2: cannot read depth file depth/000001.npy: "),
    "npy cut": ("R6.21", _file("depth/000002.npy", _cut(0.5)),
                f"{L} 3: cannot read depth file depth/000002.npy: "),
    "instance floats": ("R6.21", _instance(_npy(np.zeros((480, 640))), "npy"),
                        f"{L} 1: cannot read instance file instance/000000.npy: its array holds "
                        "float64, not integer ids"),
    "instance 8-bit": ("R6.21", _instance(_png(np.zeros((480, 640), np.uint8)), "png"),
                       f"{L} 1: cannot read instance file instance/000000.png: it is a L image, "
                       "not 16-bit"),
    "not utf-8": ("R6.21", _line(2, b'{"rgb": "\xff"}'),
                  f"cannot read {{}}/{L} 2: UnicodeDecodeError"),
    "deep line": ("R6.21", _line(1, "[" * 100_000), f"cannot read {{}}/{L} 1: ValueError: nested too deep"),
    "huge number": ("R6.21", _row(1, fx=10**400), f"cannot read {{}}/{L} 1: OverflowError"),
    "etc hostname": ("R6.21", _row(1, rgb="../../../../etc/hostname"),
                     f"{L} 1: rgb file '../../../../etc/hostname' is outside the walk folder"),
    "absolute": ("R6.21", _row(2, depth="/etc/hostname"),
                 f"{L} 2: depth file '/etc/hostname' is outside the walk folder"),
    "beside the folder": ("R6.21", _leaves,
                          f"{L} 1: rgb file '../outside.png' is outside the walk folder"),
    "link out": ("R6.21", _link_out, f"{L} 2: rgb file 'rgb/link.png' is outside the walk folder"),
    "not a name": ("R6.21", _row(1, depth=["depth/000000.npy"]),
                   f"{L} 1: depth must be a file name, not ['depth/000000.npy']"),
}


@trial("R6.20", "R6.21")
@pytest.mark.parametrize("case", list(FOLDERS))
def test_a_bad_folder_walk_is_one_line_naming_its_file_and_line(cli, walks, tmp_path, case):
    _, damage, said = FOLDERS[case]
    folder = folder_copy(walks, tmp_path)
    damage(folder)
    line = refused(cli, walks, folder, tmp_path)
    assert said.format(folder) in line, line


def _flip_tail(path: Path) -> None:
    """The last 30 bytes flipped: the data chunk's CRC and the end chunk (PIL: SyntaxError,
    broken PNG file)."""
    data = bytearray(path.read_bytes())
    data[-30:] = bytes(b ^ 0xFF for b in data[-30:])
    path.write_bytes(bytes(data))


@trial("R6.21")
@pytest.mark.parametrize("damage", [_cut(1 / 3), _flip_tail], ids=["cut at a third", "tail"])
def test_a_png_damaged_mid_walk_is_one_line_naming_it(cli, walks, tmp_path, damage):
    """Its header reads, so the walk opens; decoding the third frame finds the damage. The
    steps done are kept in a partial episode."""
    folder = folder_copy(walks, tmp_path)
    damage(folder / "rgb" / "000002.png")
    result = replay(cli, walks, folder, tmp_path / "out")
    line = one_error_line(result)
    assert f"{folder}/poses.jsonl line 3: cannot read rgb file rgb/000002.png: " in line, line
    assert "walk copy: 3 frames" in result.stdout
    assert json.loads((tmp_path / "out" / "episode.json").read_text())["status"] == "failed"


@trial("R6.21")
def test_a_folder_walk_reads_no_file_outside_it(walks, tmp_path, monkeypatch):
    """The paths are checked when poses.jsonl is read: no image outside is ever opened."""
    from PIL import Image

    from efficienteqa.envs.recorded import open_recording
    from efficienteqa.errors import EfficientEQAError

    folder = folder_copy(walks, tmp_path)
    _leaves(folder)
    opened: list[str] = []
    real = Image.open
    monkeypatch.setattr(Image, "open", lambda path, *a, **k: opened.append(str(path)) or
                        real(path, *a, **k))
    with pytest.raises(EfficientEQAError, match="outside the walk folder"):
        open_recording(str(folder))
    assert opened == []


# ---------------------------------------------------------------- R6.29-R6.31: ros2

@trial("R6.29")
@pytest.mark.parametrize("params", [None, "good.toml"])
def test_ros2_without_ros_is_one_line(cli, walks, tmp_path, params):
    try:
        import rclpy  # noqa: F401
        pytest.skip("ROS 2 is sourced here")
    except ImportError:
        pass
    scene = "ros2"
    if params:
        (tmp_path / params).write_text('map_frame = "map"\n')
        scene = f"ros2:{tmp_path / params}"
    line = one_error_line(cli("ask", QUESTION, "--scene", scene, *walks.backends, "--out",
                              str(tmp_path / "out")))
    assert "ROS 2 is not sourced: Python cannot import rclpy" in line


ROS2 = {  # the parameters file -> what is said
    "bad toml": ('color_topic = "/x\n', "is not valid TOML"),
    "unknown key": ('colour_topic = "/x"\n', "unknown ROS 2 parameter 'colour_topic' in {} "
                                              "(did you mean 'color_topic'?)"),
    "wrong type": ("move_timeout_s = \"long\"\n", "ROS 2 parameter move_timeout_s in {} must be a "
                                                  "float, not 'long'"),
    "missing": (None, "no ROS 2 parameters file {}"),
    "folder": ("/", "no ROS 2 parameters file {}"),
    "deep": ("a = " + "[" * 100_000 + "\n", "{} is not valid TOML"),
}


@trial("R6.30")
@pytest.mark.parametrize("case", list(ROS2))
def test_a_bad_ros2_parameters_file_is_one_line_before_rclpy(cli, walks, tmp_path, case,
                                                            monkeypatch):
    text, said = ROS2[case]
    path = tmp_path / "p.toml"
    if text == "/":
        path.mkdir()
    elif text is not None:
        path.write_text(text)
    monkeypatch.setitem(sys.modules, "rclpy", None)  # checked before rclpy
    line = one_error_line(cli("ask", QUESTION, "--scene", f"ros2:{path}", *walks.backends,
                              "--out", str(tmp_path / "out")))
    assert said.format(path) in line and "rclpy" not in line


@trial("R6.31")
def test_a_ros2_parameters_file_that_is_not_utf8_is_one_line(cli, walks, tmp_path):
    path = tmp_path / "p.toml"
    path.write_bytes(b'map_frame = "\xff\xfe"\n')
    line = one_error_line(cli("ask", QUESTION, "--scene", f"ros2:{path}", *walks.backends,
                              "--out", str(tmp_path / "out")))
    assert f"cannot read the ROS 2 parameters file {path}: 'utf-8' codec can't decode" in line
