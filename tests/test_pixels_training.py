"""Training data, network and training loop of pixel perception (small houses, tiny nets)."""

import json
import sys

import numpy as np
import pytest
import torch

from conftest import needs_egl
from efficienteqa.errors import EfficientEQAError
from efficienteqa.perception.pixels.batches import CropSampler, class_weights, losses
from efficienteqa.perception.pixels.dataset import load_shards, render_dataset
from efficienteqa.perception.pixels.frames import build_vocabulary, render_house
from efficienteqa.perception.pixels.houses import parse_seeds
from efficienteqa.perception.pixels.net import (
    IGNORE,
    PixelNet,
    Vocabulary,
    load_weights,
    predict,
    save_weights,
)
from efficienteqa.perception.pixels.train import TrainConfig, train

TINY = (4, 8, 8, 8, 8)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Three frames of one training and one validation house (box furniture)."""
    out = tmp_path_factory.mktemp("pixels-data")
    render_dataset(range(3000, 3001), out, frames_per_house=3, seed=0, progress=False, workers=1,
                   assets="builtin")
    render_dataset(range(3900, 3901), out, frames_per_house=3, seed=0, progress=False, workers=1,
                   assets="builtin")
    return out


def test_vocabulary_names_rooms_doors_and_split_categories():
    vocab = build_vocabulary()
    cats = vocab.categories
    assert cats[:2] == ("void", "wall")
    assert {"floor:living room", "floor:bedroom", "floor:hallway"} <= set(cats)
    assert "floor:guest bedroom" not in cats
    assert {"door", "floor lamp", "table lamp", "ceiling lamp", "potted plant", "cup"} <= set(cats)
    assert "lamp" not in cats
    assert len(vocab.colours) == 12 and vocab.states == ("on", "off", "open", "closed")
    assert Vocabulary.from_json(json.loads(json.dumps(vocab.to_json()))) == vocab


@needs_egl
def test_frames_have_consistent_shapes_and_labels(data):
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.geometry import Pose2D

    meta = json.loads((data / "meta.json").read_text())
    assert meta["houses"] == [3000, 3900] and meta["frames"] == 6
    vocab = Vocabulary.from_json(meta["vocabulary"])
    frames = load_shards(data, [3000])
    assert frames["rgb"].shape == (3, 240, 320, 3) and frames["rgb"].dtype == np.uint8
    assert frames["depth"].shape == (3, 240, 320) and frames["depth"].dtype == np.float16
    for key in ("category", "colour", "state"):
        assert frames[key].shape == (3, 240, 320) and frames[key].dtype == np.uint8
    assert sorted(frames["kind"].tolist()) == ["door", "random", "surface"]
    floors = [vocab.categories.index(c) for c in vocab.categories if c.startswith("floor:")]
    assert np.isin(frames["category"], floors).any()
    with SyntheticEnv.from_seed(3000, assets="builtin") as env:
        by_id = {o.id: o for o in env.house.objects}
        for i, (x, y, yaw) in enumerate(frames["pose"].tolist()):
            obs = env.observe(Pose2D(x, y, yaw))
            inst = obs.instance[1::2, 1::2]
            cat = frames["category"][i]
            assert (cat[obs.depth_m[1::2, 1::2] == 0] == 0).all()  # nothing hit: void
            for oid in set(np.unique(inst[inst > 0]).tolist()) & set(by_id):
                want = vocab.index(by_id[oid].category)
                assert (cat[inst == oid] == (IGNORE if want is None else want)).all()
            # floor pixels carry the type of the room under them
            points = obs.depth_m[1::2, 1::2] > 0
            for k in floors:
                assert (inst[(cat == k) & points] == 0).all()
            labels = env.scene_labels()
            from efficienteqa.geometry import backproject

            world = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[1::2, 1::2]
            ys, xs = np.nonzero(np.isin(cat, floors))
            for yy, xx in list(zip(ys.tolist(), xs.tolist()))[::500]:
                room = labels.room_at(float(world[yy, xx, 0]), float(world[yy, xx, 1]))
                assert room is not None
                name = vocab.categories[cat[yy, xx]][len("floor:"):]
                assert room.replace("guest ", "") == name


@needs_egl
def test_rendering_is_deterministic_by_seed():
    vocab = build_vocabulary()
    a = render_house(3001, 2, 7, vocab, assets="builtin")
    b = render_house(3001, 2, 7, vocab, assets="builtin")
    c = render_house(3001, 2, 8, vocab, assets="builtin")
    for key in ("rgb", "category", "colour", "state", "pose"):
        assert np.array_equal(a[key], b[key])
    assert not np.array_equal(a["pose"], c["pose"])


@needs_egl
def test_a_tiny_net_learns_and_its_weights_round_trip(data, tmp_path):
    vocab = build_vocabulary()
    frames = load_shards(data, [3000])
    torch.manual_seed(0)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # a tiny net: threads only wait for each other
    sampler = CropSampler(frames, vocab, (32, 48), np.random.default_rng(0))
    x, cat, col, st = sampler.batch(4)
    assert x.shape == (4, 4, 32, 48) and cat.shape == (4, 32, 48)
    net = PixelNet(vocab, TINY)
    weights = class_weights(frames["category"], len(vocab.categories))
    opt = torch.optim.AdamW(net.parameters(), lr=1e-2)
    first = None
    for _ in range(15):
        loss, _ = losses(net, x, cat, col, st, weights)
        first = float(loss.detach()) if first is None else first
        opt.zero_grad()
        loss.backward()
        opt.step()
    torch.set_num_threads(threads)
    assert float(loss.detach()) < 0.8 * first

    path = tmp_path / "w" / "pixels.pt"
    save_weights(path, net, vocab, {"note": "test"})
    loaded, vocab2, meta = load_weights(path)
    assert vocab2 == vocab and meta["note"] == "test" and meta["widths"] == list(TINY)
    rgb = np.zeros((480, 640, 3), np.uint8)
    depth = np.full((480, 640), 2.0, np.float32)
    out = predict(loaded, rgb, depth)
    assert out.category.shape == (240, 320) and out.confidence.shape == (240, 320)
    assert out.state.max() <= len(vocab.states)

    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    path.write_bytes(bytes(raw))
    with pytest.raises(EfficientEQAError) as err:
        load_weights(path)
    assert "sha256" in str(err.value) and "\n" not in str(err.value)
    path.unlink()
    with pytest.raises(EfficientEQAError, match="missing"):
        load_weights(path)


def _shard(path, house, frames=2):
    """A shard of ``frames`` blank frames of ``house``, in the arrays ``render_dataset`` writes."""
    np.savez_compressed(path, rgb=np.zeros((frames, 240, 320, 3), np.uint8),
                        depth=np.ones((frames, 240, 320), np.float32),
                        category=np.ones((frames, 240, 320), np.uint8),
                        colour=np.full((frames, 240, 320), IGNORE, np.uint8),
                        state=np.full((frames, 240, 320), IGNORE, np.uint8),
                        house=np.full(frames, house, np.int32))


@pytest.mark.trial("N.4")
def test_a_torn_shard_or_mistyped_meta_is_one_line_before_training(tmp_path):
    """Fault trial N.4: a shard cut in half ended ``perception train`` in ``BadZipFile: File is
    not a zip file``, and meta.json's ``houses`` of another type in a ``TypeError``. Both are
    one line naming the file."""
    from efficienteqa.perception.pixels.train import check_data

    data = tmp_path / "data"
    data.mkdir()
    meta = {"vocabulary": build_vocabulary().to_json(), "houses": [3000, 3900]}
    (data / "meta.json").write_text(json.dumps(meta))
    _shard(data / "houses-3000-3000.npz", 3000)
    _shard(data / "houses-3900-3900.npz", 3900)
    whole = (data / "houses-3900-3900.npz").read_bytes()
    (data / "houses-3900-3900.npz").write_bytes(whole[:len(whole) // 2])
    config = TrainConfig(steps=1000, batch=1, crop=(32, 48), widths=TINY, threads=1)
    with pytest.raises(EfficientEQAError) as err:
        train(data, tmp_path / "w.pt", config, log=sys.stdout)
    message = str(err.value)
    assert "houses-3900-3900.npz is not a readable shard of frames" in message
    assert "\n" not in message and "renders the missing shards only" in message
    assert not (tmp_path / "w.ckpt").exists() and not (tmp_path / "w.pt").exists()
    (data / "houses-3900-3900.npz").write_bytes(b"not a zip file")  # read as a pickle: refused
    with pytest.raises(EfficientEQAError, match="is not a readable shard of frames"):
        load_shards(data)
    for houses in (5, None, ["3000"], [[3000]]):
        (data / "meta.json").write_text(json.dumps({**meta, "houses": houses}))
        with pytest.raises(EfficientEQAError, match="'houses' must be a list of house seeds"):
            check_data(data)


def test_validation_frames_are_read_before_training(tmp_path, monkeypatch):
    """Fault trial N.4: the validation houses' frames were read only once every step was done,
    so a shard whose arrays could not be read cost the whole training. They are read first."""
    from efficienteqa.perception.pixels import train as training

    data = tmp_path / "data"
    data.mkdir()
    (data / "meta.json").write_text(json.dumps({"vocabulary": build_vocabulary().to_json(),
                                                "houses": [3000, 3900]}))
    _shard(data / "houses-3000-3000.npz", 3000)
    _shard(data / "houses-3900-3900.npz", 3900)

    def load(folder, houses=None):
        if houses == [3900]:
            raise EfficientEQAError("the validation shard cannot be read")
        return load_shards(folder, houses)

    monkeypatch.setattr(training, "load_shards", load)
    log = tmp_path / "log.txt"
    with log.open("w") as out, pytest.raises(EfficientEQAError, match="validation shard"):
        train(data, tmp_path / "w.pt", TrainConfig(steps=2, batch=1, crop=(32, 48), widths=TINY,
                                                   threads=1), log=out)
    assert "step" not in log.read_text()


@pytest.mark.trial("N.5")
def test_weights_that_match_their_checksum_but_not_the_network_are_one_line(tmp_path):
    """Fault trial N.5: a .pt and .json that agree on the sha256 but not on the network (other
    widths or vocabulary in the .json, or bytes that are no state dict in the .pt) ended in
    ``RuntimeError: size mismatch`` or ``UnpicklingError`` tracebacks."""
    from efficienteqa.perception.pixels.net import metadata_path, sha256_of

    vocab = build_vocabulary()
    path = tmp_path / "pixels.pt"
    json_path = save_weights(path, PixelNet(vocab, TINY), vocab, {})
    meta = json.loads(json_path.read_text())

    def broken(**changes):
        json_path.write_text(json.dumps({**meta, "sha256": sha256_of(path), **changes}))
        with pytest.raises(EfficientEQAError) as err:
            load_weights(path)
        assert "\n" not in str(err.value) and "Traceback" not in str(err.value)
        return str(err.value)

    assert "do not fit the network pixels.json describes: Error(s) in loading state_dict" in \
        broken(widths=[4, 8, 8, 8, 16])
    vocabulary = {**meta["vocabulary"], "colours": meta["vocabulary"]["colours"][:-1]}
    assert "do not fit the network" in broken(vocabulary=vocabulary)
    assert "widths must be whole numbers" in broken(widths=[4, 8, 8, 8, 10**9])
    assert "widths must be whole numbers" in broken(widths=[4, 8, 8, 8, "8"])
    assert "widths needs 5 numbers" in broken(widths=[4, 8])
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    assert "do not fit the network" in broken()
    torch.save([1, 2, 3], path)
    assert "do not fit the network" in broken()
    assert metadata_path(path) == json_path


@needs_egl
def test_train_writes_weights_and_validation_figures(data, tmp_path):
    out = tmp_path / "pixels.pt"
    config = TrainConfig(steps=3, batch=2, crop=(32, 48), widths=TINY, threads=1)
    record = train(data, out, config, command="test", log=sys.stdout)
    assert record["steps_done"] == 3 and record["data"]["validation_houses"] == [3900]
    assert 0.0 <= record["validation"]["pixel_accuracy"] <= 1.0
    _, _, meta = load_weights(out)
    assert meta["command"] == "test" and meta["seed"] == 0 and "code_version" in meta


def _cli(monkeypatch, capsys, *args):
    from efficienteqa import cli

    monkeypatch.setattr(sys, "argv", ["efficienteqa", *args])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    return exit_info.value.code, capsys.readouterr().out


@pytest.mark.parametrize("seeds", ["abc", "3000-29", "100-120", "3990-4005"])
def test_bad_seed_ranges_are_refused(seeds, monkeypatch, capsys, tmp_path):
    code, out = _cli(monkeypatch, capsys, "perception", "dataset", "--seeds", seeds, "--out",
                     str(tmp_path / "d"))
    assert code == 1 and len(out.strip().splitlines()) == 1 and "error" in out
    assert not (tmp_path / "d").exists()
    with pytest.raises(EfficientEQAError):
        parse_seeds(seeds)


def test_train_refuses_missing_or_empty_data_and_unwritable_out(monkeypatch, capsys, tmp_path):
    (tmp_path / "empty").mkdir()
    data = tmp_path / "data"
    data.mkdir()
    (data / "meta.json").write_text(json.dumps({"vocabulary": build_vocabulary().to_json(),
                                                "houses": [3000]}))
    (data / "houses-3000-3000.npz").write_bytes(b"")
    for folder in (tmp_path / "none", tmp_path / "empty"):
        code, out = _cli(monkeypatch, capsys, "perception", "train", "--data", str(folder),
                         "--out", str(tmp_path / "w.pt"), "--steps", "1")
        assert code == 1 and len(out.strip().splitlines()) == 1 and "frames" in out
    code, out = _cli(monkeypatch, capsys, "perception", "train", "--data", str(data), "--out",
                     str(tmp_path), "--steps", "1")
    assert code == 1 and len(out.strip().splitlines()) == 1 and "cannot write" in out


class _Touch:
    """A pickle that would create ``path`` when unpickled as code."""

    def __init__(self, path):
        self.path = path

    def __reduce__(self):
        from pathlib import Path

        return (Path.touch, (Path(self.path),))


@pytest.mark.trial("4.8")
@pytest.mark.filterwarnings("ignore:Detected pickle protocol")
def test_a_checkpoint_is_read_as_weights_never_run_as_code(tmp_path):
    """Fault trial 4.8: ``--resume`` loaded the training checkpoint with ``weights_only=False``:
    a .ckpt beside --out could run code. It is read as tensors and numbers only; anything else
    is one line."""
    import pickle

    from efficienteqa.perception.pixels.train import checkpoint_path

    data = tmp_path / "data"
    data.mkdir()
    (data / "meta.json").write_text(json.dumps({"vocabulary": build_vocabulary().to_json(),
                                                "houses": [3000]}))
    _shard(data / "houses-3000-3000.npz", 3000)
    out, marker = tmp_path / "w.pt", tmp_path / "PWNED"
    config = TrainConfig(steps=2, batch=1, crop=(32, 48), widths=TINY, threads=1, resume=True)
    for payload in (pickle.dumps(_Touch(marker)), b"not a checkpoint"):
        checkpoint_path(out).write_bytes(payload)
        with pytest.raises(EfficientEQAError, match="is not a readable training checkpoint"):
            train(data, out, config, log=sys.stdout)
        assert not marker.exists() and not out.exists()
    torch.save({"format": 1, "schedule": {}, "data": {}}, checkpoint_path(out))
    with pytest.raises(EfficientEQAError, match="was written by another training"):
        train(data, out, config, log=sys.stdout)
