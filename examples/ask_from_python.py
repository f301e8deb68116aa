"""Ask a question from Python: one episode in a synthetic house, its answer and its records.

    python examples/ask_from_python.py                      # the offline default (local model)
    python examples/ask_from_python.py --vlm openai:gpt-4o --perception rgb
    python examples/ask_from_python.py --vlm openai:MODEL@http://127.0.0.1:8000/v1 --perception rgb

``run_config`` makes the run's whole configuration from a preset and settings named as the
command line names them (``backends.vlm`` is ``--backends.vlm``), checked as the command line
checks them; ``ask`` opens the scene, runs explore -> stop -> answer and writes
``episode.json`` and ``report.html`` into the output folder. ``efficienteqa config`` prints the
same configuration as a TOML file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from efficienteqa.ask import ask
from efficienteqa.config.backends import Stack
from efficienteqa.config.presets import run_config
from efficienteqa.stack import default_relevancy


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("question", nargs="?", default="What is on the desk in the office?")
    parser.add_argument("--scene", default="synthetic:0")
    parser.add_argument("--vlm", default=Stack().vlm)
    parser.add_argument("--perception", default="semantic", help="semantic | pixels | rgb")
    parser.add_argument("--max-steps", type=int, default=None)
    parser.add_argument("--assets", default="sh3d", help="sh3d (CC0 furniture) | builtin (boxes)")
    parser.add_argument("--out", type=Path, default=Path("out/example"))
    args = parser.parse_args(argv)

    run = run_config(None, {"backends.vlm": args.vlm,
                            "backends.perception": args.perception,
                            "backends.relevancy": default_relevancy(args.perception),
                            "explore.max_steps": args.max_steps,
                            "scene.assets": args.assets})
    done = ask(args.question, args.scene, args.out, run=run)
    result = done.result
    print(f"answer: {result.answer} (confidence {result.confidence:.2f})")
    print(f"steps: {result.steps}, stopped by {result.stop_reason}")
    print(f"report: {done.report_html}")


if __name__ == "__main__":
    main()
