"""The Blind LLM baseline (SPEC 3.6): the question only, no observations; the model must guess
when unsure. The same VC answer (M guesses -> group -> argmax) as the RAG answer."""

from __future__ import annotations

from efficienteqa.answer.vc import PROMPTS, answer_example, vc_answer
from efficienteqa.models.base import ChatModel
from efficienteqa.vc.grouping import Grouper
from efficienteqa.vc.parse import AnswerResult, M
from efficienteqa.vc.prompts import load_prompt


def blind_answer(model: ChatModel, question: str, grouper: Grouper, *, m: int = M,
                 max_tokens: int = 96) -> AnswerResult:
    """M guesses from the question alone (``answer/prompts/blind.txt``), grouped, argmax."""
    prompt = load_prompt("blind", PROMPTS).format(question=question, m=m, example=answer_example(question))
    return vc_answer(model, prompt, (), question, grouper, m, max_tokens)
