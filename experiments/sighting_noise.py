"""What sightings read by a model are worth to the steering, and what reading by a model costs.

    python -m experiments.sighting_noise --limit 48 --out out/sightings frontier-only miss20-room10
    efficienteqa report out/sightings/* --paired-against out/sightings/frontier-only --markdown

It runs the main table's questions (the synthetic split's first LIMIT: houses 100-999, never
used for tuning) once per setting, each an ``efficienteqa eval`` in this process with the offline
default stack (synthetic houses, semantic-sensor perception, Qwen2.5-Coder-1.5B on llama.cpp,
MiniLM relevancy, the rule judge) but for where the steering's sightings come from:

- ``frontier-only``: the main table's frontier-only row (no steering; its gate as the default's);
- ``rules``: the default (the semantic sensor's own sightings, read from the labels);
- ``model``: the local model reads the description, one call per step (``--sightings model``);
- ``exact``, ``miss20-room10``, ...: the labels-backed test VLM (``tests/labels_vlm.py``) over the
  image path: boxes from the truth, projected with depth, with misses (``missN``: N% of the
  things in view left out), wrong rooms (``roomN``) and displaced boxes (``shiftN``) at set rates.

The runs' back-ends say where the sightings came from (``sightings`` in each row's back-ends);
the labels-backed model's calls are not the chat model's, so they are in no call or token count.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def _errors(name: str) -> Any:
    sys.path.insert(0, str(ROOT / "tests"))
    from labels_vlm import Errors

    if name == "exact":
        return Errors()
    rates = dict(re.findall(r"(miss|room|shift)(\d+)", name))
    if not rates or "-".join(f"{k}{v}" for k, v in rates.items()) != name:
        raise SystemExit(f"unknown setting {name!r}: frontier-only, rules, model, exact or e.g. "
                         "miss20-room10-shift10")
    return Errors(miss=int(rates.get("miss", 0)) / 100, wrong_room=int(rates.get("room", 0)) / 100,
                  displace=int(rates.get("shift", 0)) / 100)


def spec_for(name: str) -> Any:
    from efficienteqa.config.presets import build_config, build_stack, load_preset
    from efficienteqa.eval.methods import RunSpec
    from efficienteqa.stack import SIGHTINGS

    options = dict(load_preset("frontier-only" if name == "frontier-only" else "default"))
    if name == "model":
        options["sightings"] = "model"
    elif name not in ("frontier-only", "rules"):
        errors = _errors(name)
        from labels_vlm import LabelsSightings

        if f"labels:{name}" not in SIGHTINGS:
            SIGHTINGS.register(f"labels:{name}", lambda perception, env, **_: LabelsSightings(
                perception, env.scene_labels(), errors))
        options["sightings"] = f"labels:{name}"
    return RunSpec.of(method=options.get("method") or "efficienteqa", dataset="synthetic",
                   stack=build_stack(options), config=build_config(options), judge=None)


def run(names: list[str], limit: int, out: Path) -> None:
    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.runner import run_eval

    questions = load_dataset("synthetic", limit=limit)
    for name in names:
        spec = spec_for(name)
        result = run_eval(spec, questions, out / name, on_episode=_progress(name))
        print(f"{name}: {result}", flush=True)


def _progress(name: str) -> Any:
    def say(row: dict[str, Any]) -> None:
        print(f"{name} {row['id']} {row['status']} {row.get('steps')} "
              f"{(row.get('rule') or {}).get('correct')}", flush=True)
    return say


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("settings", nargs="+")
    parser.add_argument("--limit", type=int, default=48)
    parser.add_argument("--out", type=Path, default=Path("out/sightings"))
    args = parser.parse_args(argv)
    for name in args.settings:
        spec_for(name)  # a bad setting fails before any episode
    run(args.settings, args.limit, args.out)


if __name__ == "__main__":
    main()
