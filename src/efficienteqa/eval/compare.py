"""Comparisons between runs: paired differences over the questions two runs share, groups of
runs that differ in one setting (the paper's ablation tables), and labels made unique.

Kept apart from one run's summary (``eval.summary``) because each of these reads several
``RunSummary`` at once.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import Any

from efficienteqa.eval.stats import PairedDifference, is_number, mean, mean_interval
from efficienteqa.eval.summary import RunSummary

# Settings that change no result: left out when runs are compared for ablations.
NEUTRAL_SETTINGS = frozenset({"cache"})


def paired(run: RunSummary, reference: RunSummary, reference_label: str = "") -> PairedDifference:
    """Paired differences of ``run`` against ``reference`` over the questions both answered,
    matched by episode id: the per-question differences, their mean and its bootstrap interval."""
    judge = run.accuracy_judge if run.accuracy_judge == reference.accuracy_judge else ""
    ids = [k for k in run.episode_accuracy if k in reference.episode_accuracy] if judge else []
    accuracy = [run.episode_accuracy[k] - reference.episode_accuracy[k] for k in ids]
    both = [k for k in run.episode_steps if k in reference.episode_steps]
    steps = [run.episode_steps[k] - reference.episode_steps[k] for k in both]
    return PairedDifference(reference=reference_label or reference.label, judge=judge, n=len(ids),
                            accuracy=mean(accuracy), accuracy_ci=mean_interval(accuracy),
                            n_steps=len(both), steps=mean(steps), steps_ci=mean_interval(steps))


def ablations(summaries: Sequence[RunSummary], key: str) -> list[list[RunSummary]]:
    """Groups of at least two runs of one method on one dataset whose settings differ only in
    ``key`` (e.g. "z_th", "top_k"), each sorted by that value: the paper's Tables II and III."""
    groups: dict[tuple[Any, ...], list[RunSummary]] = {}
    for s in summaries:
        if key not in s.settings:
            continue
        rest = tuple(sorted((k, repr(v)) for k, v in s.settings.items()
                            if k != key and k not in NEUTRAL_SETTINGS))
        groups.setdefault((s.dataset, s.method, rest), []).append(s)
    return [sorted(g, key=lambda s: _order(s.settings[key])) for g in groups.values()
            if len({repr(s.settings[key]) for s in g}) > 1]


def _order(value: Any) -> tuple[int, float, str]:
    """Numbers first, ascending; anything else (None: the default budget) after, by name."""
    return (0, float(value), "") if is_number(value) else (1, 0.0, str(value))


def distinct_labels(summaries: Sequence[RunSummary]) -> list[str]:
    """Each run's label, made unique where two runs share one: first by the back-ends that tell
    them apart (VLM, perception, sightings, relevancy), then by the folder they came from."""
    out = [s.label for s in summaries]
    for keys in (("vlm", "perception", "sightings", "relevancy", "judge"), ("source",)):
        counts = Counter(out)
        for i, s in enumerate(summaries):
            if counts[out[i]] > 1:
                same = [t for t in summaries if t.label == s.label]
                extra = [_shown(k, _lookup(s, k)) for k in keys
                         if len({str(_lookup(t, k)) for t in same}) > 1]
                if extra:
                    out[i] = f"{out[i]} ({', '.join(extra)})"
    return out


def _shown(key: str, value: Any) -> str:
    """A back-end that tells two runs apart, as their labels say it: the judge as "judge X", or
    "rule judge only" where the run had no LLM judge; another missing one as "no KEY"."""
    if key == "judge":
        return f"judge {value}" if value else "rule judge only"
    return f"no {key}" if value is None else str(value)


def _lookup(s: RunSummary, key: str) -> Any:
    return s.source if key == "source" else s.settings.get(key)
