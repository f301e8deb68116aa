"""Token probabilities for the white-box baselines (DESIGN 3.6): the same quantities as verbalized
confidence (P(letter), P(yes)), read from a model's top log-probabilities instead of its words."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import ChatModel, TokenLogprob
from efficienteqa.vc.numbers import to_float
from efficienteqa.vc.yes_no import DEFAULT_P_YES

TOP_LOGPROBS = 10  # alternatives asked for per generated token

LogprobInput = TokenLogprob | Sequence[TokenLogprob] | Sequence[tuple[str, float]] | Mapping[str, float]


def require_logprobs(model: ChatModel) -> None:
    """Fail before the first call when ``model`` cannot give token log-probabilities."""
    if not model.capabilities.logprobs:
        raise EfficientEQAError(f"model {model.name!r} does not return token log-probabilities",
                                fix="use explore-eqa-blackbox (verbalized confidence), or a server "
                                    "that gives logprobs (llama.cpp, vLLM)")


def _positions(top: LogprobInput | None) -> list[list[tuple[str, float]]]:
    """The alternatives (token, logprob) at each generated position; a mapping or a flat list of
    pairs is one position."""
    if top is None:
        return []
    if isinstance(top, Mapping):
        return [list(top.items())]
    if isinstance(top, TokenLogprob):
        top = [top]
    out: list[list[tuple[str, float]]] = []
    flat: list[tuple[str, float]] = []
    for item in top:
        if isinstance(item, TokenLogprob):
            alts = list(item.top)
            if all(t != item.token for t, _ in alts):
                alts.append((item.token, item.logprob))
            out.append(alts)
        elif isinstance(item, (tuple, list)) and len(item) == 2:
            flat.append((item[0], item[1]))
    return out + ([flat] if flat else [])


def _token_key(token: object) -> str:
    """``" (B"``, ``"ĠB"``, ``"▁b."``, ``"Yes!"`` -> ``"B"``/``"YES"``: tokenizer space marks, brackets,
    punctuation and case dropped."""
    return str(token).replace("Ġ", " ").replace("▁", " ").strip().strip("()[]{}.:;,!?*\"'").upper()


def _logaddexp(a: float, b: float) -> float:
    hi = max(a, b)
    return hi + math.log1p(math.exp(min(a, b) - hi))


def _softmax_at(alts: Sequence[tuple[str, float]], allowed: Sequence[str]) -> dict[str, float] | None:
    """Softmax over ``allowed`` keys among one position's alternatives; None if none is there."""
    mass: dict[str, float] = {}
    for tok, lp in alts:
        key, value = _token_key(tok), to_float(lp)
        if key in allowed and value is not None and math.isfinite(value):
            mass[key] = _logaddexp(mass[key], value) if key in mass else value
    if not mass:
        return None
    hi = max(mass.values())
    exp = {k: math.exp(v - hi) for k, v in mass.items()}
    total = sum(exp.values())
    return {k: exp.get(k, 0.0) / total for k in allowed}


def _softmax_first(top: LogprobInput | None, allowed: Sequence[str]) -> dict[str, float] | None:
    """Softmax over ``allowed`` keys at the first position whose alternatives include one."""
    for alts in _positions(top):
        probs = _softmax_at(alts, allowed)
        if probs is not None:
            return probs
    return None


def letter_probs_from_logprobs(top_logprobs: LogprobInput | None, letters: Sequence[str]
                               ) -> dict[str, float]:
    """P(letter) from token log-probabilities, softmax-normalised over ``letters`` (tokens
    matched ignoring case, spaces and brackets); uniform when no letter is among them."""
    keys = [str(x).strip().upper() for x in letters]
    probs = _softmax_first(top_logprobs, keys)
    if not letters:
        return {}
    return {x: (probs[k] if probs else 1.0 / len(letters)) for x, k in zip(letters, keys)}


def yes_prob_or_none(top_logprobs: LogprobInput | None) -> float | None:
    """P(yes) over {yes, no} from token log-probabilities; None when neither is there."""
    probs = _softmax_first(top_logprobs, ["YES", "NO"])
    return probs["YES"] if probs else None


def yes_prob_from_logprobs(top_logprobs: LogprobInput | None) -> float:
    """P(yes) over {yes, no} from token log-probabilities; ``DEFAULT_P_YES`` when neither is there."""
    p = yes_prob_or_none(top_logprobs)
    return DEFAULT_P_YES if p is None else p


def _has_newline(token: str) -> bool:
    return "\n" in token or "Ċ" in token  # Ċ: a byte-level BPE tokenizer's raw newline


def _split_first_line(tokens: list[TokenLogprob]) -> tuple[list[TokenLogprob], list[TokenLogprob]]:
    """The reply's tokens up to the end of its first non-blank line, and the rest."""
    end, seen_text = len(tokens), False
    for i, t in enumerate(tokens):
        head = t.token.replace("Ċ", "\n").split("\n")[0]
        if _has_newline(t.token) and (seen_text or head.strip()):
            end = i + 1 if head.strip() else i  # "B\n" ends the line it belongs to
            break
        seen_text = seen_text or bool(t.token.strip())
    return tokens[:end], tokens[end:]


def letter_read(top_logprobs: LogprobInput | None, letters: Sequence[str], *,
                first_line: bool = False) -> bool:
    """Whether a letter of ``letters`` is among the alternatives of some position (of the first
    line only, as ``letter_and_yes_probs`` reads it, with ``first_line``): where none is, the
    letter probabilities are uniform, which the caller must count as a problem."""
    if first_line and isinstance(top_logprobs, Sequence) and all(
            isinstance(t, TokenLogprob) for t in top_logprobs):
        top_logprobs = _split_first_line(list(top_logprobs))[0]  # type: ignore[arg-type]
    return _softmax_first(top_logprobs, [str(x).strip().upper() for x in letters]) is not None


def letter_and_yes_probs(tokens: Sequence[TokenLogprob], letters: Sequence[str]
                         ) -> tuple[dict[str, float], float]:
    """ExploreEQA's two-line white-box reply (a letter, then yes/no): P(letter) on the first
    line, P(yes) on the yes/no line after it (blank lines skipped; in a one-line reply, the
    tokens after the letter). Alternatives at the letter token ("Yes" as another way to start
    the reply) never count as the yes/no answer."""
    first_line, rest = _split_first_line(list(tokens))
    keys = [str(x).strip().upper() for x in letters]
    at = next((i for i, alts in enumerate(_positions(first_line)) if _softmax_at(alts, keys)), None)
    if not any(t.token.strip() for t in rest):  # one line: yes/no after the letter
        rest = first_line[at + 1:] if at is not None else first_line
    return letter_probs_from_logprobs(first_line, letters), yes_prob_from_logprobs(rest)
