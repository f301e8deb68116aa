"""`efficienteqa eval` on the questions of one category only: the same command and options,
with the questions outside CATEGORY left out after ``--eval.limit`` took the dataset's first N
(so the episodes are the full run's of that category). ``--close-reads N`` (first, before the
eval options) sets the pixel perception's close reads for the run (``PixelPerception.load``'s
default, CLOSE_READS; 0 is off); run.json does not record it.

    python -m experiments.category_eval identification --preset pixels --eval.limit 48 \
        --judge none --out out/ident-pixels
    python -m experiments.category_eval identification --close-reads 0 --preset pixels \
        --eval.limit 48 --judge none --out out/ident-pixels-off
"""

from __future__ import annotations

import sys
from typing import Any

import efficienteqa.datasets as datasets
from efficienteqa.cli import main as cli


def main() -> None:
    """CATEGORY, then the options of ``efficienteqa eval``."""
    if len(sys.argv) < 2 or sys.argv[1].startswith("-"):
        sys.exit("usage: python -m experiments.category_eval CATEGORY [--close-reads N] "
                 "[eval options]")
    category, options = sys.argv[1], sys.argv[2:]
    if options[:1] == ["--close-reads"]:
        from efficienteqa.perception.pixels.backend import PixelPerception

        weights, votes, _ = PixelPerception.load.__func__.__defaults__  # type: ignore[attr-defined]
        PixelPerception.load.__func__.__defaults__ = (  # type: ignore[attr-defined]
            weights, votes, int(options[1]))
        options = options[2:]
    load = datasets.load_dataset

    def only(*args: Any, **kwargs: Any) -> list[Any]:
        return [q for q in load(*args, **kwargs) if q.category == category]

    datasets.load_dataset = only  # type: ignore[assignment]  # eval imports it when it runs
    sys.argv = ["efficienteqa", "eval", *options]
    cli()


if __name__ == "__main__":
    main()
