import json
import subprocess
import sys

from conftest import needs_egl


def _run(*args, env=None):
    return subprocess.run([sys.executable, "-m", "efficienteqa.cli", *args], capture_output=True,
                          text=True, env=env, timeout=300)


@needs_egl
def test_scenes_generate_writes_every_file(tmp_path):
    result = _run("scenes", "generate", "--seed", "5", "--out", str(tmp_path), "--assets", "builtin")
    assert result.returncode == 0, result.stderr
    house = json.loads((tmp_path / "house.json").read_text())
    assert house["seed"] == 5 and house["objects"]
    lines = (tmp_path / "questions.jsonl").read_text().splitlines()
    assert len(lines) >= 5 and all(json.loads(line)["answer"] for line in lines)
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "views.png").read_bytes()[:4] == b"\x89PNG"


def test_missing_furniture_is_one_line_naming_the_fix(tmp_path):
    import os

    env = {**os.environ, "EFFICIENTEQA_FURNITURE_DIR": str(tmp_path / "none"),
           "EFFICIENTEQA_CACHE": str(tmp_path / "cache")}
    result = _run("scenes", "generate", "--out", str(tmp_path / "out"), env=env)
    assert result.returncode == 1
    assert "apt-get install sweethome3d-furniture" in result.stdout
    assert "Traceback" not in result.stdout + result.stderr
    assert len(result.stdout.strip().splitlines()) == 1
