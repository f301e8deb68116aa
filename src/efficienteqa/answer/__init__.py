"""The answer module of the paper: retrieval-augmented generation over the frame history (DESIGN 3.5)."""

from efficienteqa.answer.rag import RagAnswerer, TopK

__all__ = ["RagAnswerer", "TopK"]
