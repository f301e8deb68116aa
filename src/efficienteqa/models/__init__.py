"""Model back-ends: chat models (VLM/LLM) behind one protocol, the local llama.cpp server."""
