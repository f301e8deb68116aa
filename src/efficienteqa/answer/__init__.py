"""The answer module of the paper: retrieval-augmented generation over the frame history (SPEC 3.5)."""

from efficienteqa.answer.rag import RagAnswerer, TopK

__all__ = ["RagAnswerer", "TopK"]
