#!/usr/bin/env bash
# Idempotent set-up for raster-oracle on a Debian machine: system packages, a virtual
# environment in .venv and an editable install. Safe to run twice; the second run only checks
# and returns. `bin/setup.sh` installs what the main job needs; `bin/setup.sh --test` adds what
# the tests need (the test extras and headless Chromium for the report tests).
set -euo pipefail
mode=main
[ "${1:-}" = "--test" ] && mode=test
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

need_apt=()
# libLLVM >= 16 for Dr.Jit's LLVM backend (Debian's default LLVM 15 aborts it).
ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* /usr/lib/*/libLLVM-19.so* >/dev/null 2>&1 || need_apt+=(libllvm19)
# Headless Chromium for the report tests only; Mesa's EGL and llvmpipe for the test that
# runs the published SMAA shader (tests/test_smaa_glsl.py, through moderngl).
if [ "$mode" = test ]; then
    command -v chromium >/dev/null 2>&1 || need_apt+=(chromium)
    ls /usr/lib/x86_64-linux-gnu/libEGL_mesa.so.0 >/dev/null 2>&1 || need_apt+=(libegl1 libegl-mesa0)
    ls /usr/lib/x86_64-linux-gnu/dri/swrast_dri.so >/dev/null 2>&1 || need_apt+=(libgl1-mesa-dri)
fi
if [ "${#need_apt[@]}" -gt 0 ]; then
    if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
    echo "setup: installing system packages: ${need_apt[*]}" >&2
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >&2
fi

py="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv" >&2
    "$py" -m venv .venv
fi
stamp=".venv/.raster-oracle-$mode-stamp"
want="$(cat pyproject.toml setup.py | sha256sum | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "setup: installing raster-oracle into .venv" >&2
    .venv/bin/python -m pip install -q --upgrade pip >&2
    if [ "$mode" = test ]; then target=".[test]"; else target="."; fi
    .venv/bin/python -m pip install -q -e "$target" >&2
    echo "$want" > "$stamp"
fi
