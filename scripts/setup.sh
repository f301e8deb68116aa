#!/usr/bin/env bash
# One-time, idempotent set-up: Debian packages, a virtual environment, the package, the llama.cpp
# runtime and the local language models. Re-running it is fast: each step checks whether it is
# already done (slow artefacts are cached in ~/.cache/efficienteqa, see efficienteqa.cache).
#
#   scripts/setup.sh         what the demo needs (`make demo`): the extra `local`, Qwen2.5-Coder
#   scripts/setup.sh --dev   also the developers' tools (`make test`, `make lint`, CI): chromium for
#                            the report's screenshot test, the extras dev, vision and ray, SmolLM2
set -euo pipefail
cd "$(dirname "$0")/.."

DEV=0
case "${1:-}" in
  --dev) DEV=1 ;;
  "") ;;
  *) echo "usage: scripts/setup.sh [--dev]" >&2; exit 2 ;;
esac

# libegl1 libegl-mesa0 libgl1-mesa-dri: off-screen rendering (EGL on Mesa's llvmpipe).
# sweethome3d-furniture: the CC0 furniture of the synthetic houses.
# build-essential: the one-time portable build of llama-cpp-python when no wheel is cached.
APT_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri sweethome3d-furniture build-essential)
EXTRAS=local
MODELS=(qwen2.5-coder-1.5b)
if [ "$DEV" -eq 1 ]; then
  APT_PACKAGES+=(chromium)  # the headless browser the tests open the episode report in
  EXTRAS=dev,local,minilm,vision,ray,robot,rerun
  MODELS=(smollm2-135m qwen2.5-coder-1.5b)  # SmolLM2: the tests' fast server
fi
VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "==> installing Debian packages: ${missing[*]}"
  sudo_if_needed apt-get update -qq
  sudo_if_needed env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "==> creating virtual environment $VENV"
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/pip" install -q --upgrade pip
fi

# Reinstall the package only when its metadata or the extras changed. The stamp holds the hash of
# pyproject.toml and the extras installed; the developers' extras include the demo's.
stamp="$VENV/.efficienteqa-installed"
hash=$(sha256sum pyproject.toml | cut -d' ' -f1)
have=$(cat "$stamp" 2>/dev/null || true)
if [ "$have" != "$hash $EXTRAS" ] && { [ "$DEV" -eq 1 ] || [ "${have%% *}" != "$hash" ]; }; then
  echo "==> installing efficienteqa[$EXTRAS]"
  # torch first, pinned: the CPU build on this kind of machine; any other spec pulls GBs of CUDA.
  "$VENV/bin/pip" install -q torch==2.13.0
  "$VENV/bin/pip" install -q -e ".[$EXTRAS]"
  echo "$hash $EXTRAS" > "$stamp"
fi

# llama.cpp's portable wheel (built once, 4-5 minutes, when absent from the cache), then the local
# models: Qwen2.5-Coder-1.5B (1.1 GB, the default language model) and for the tests SmolLM2-135M
# (93 MB). The command returns at once when everything is in place.
"$VENV/bin/efficienteqa" models install "${MODELS[@]}" >/dev/null
