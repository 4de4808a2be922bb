#!/usr/bin/env bash
# The whole test suite: set up if needed, lint with ruff, then pytest.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/bin/setup.sh" --test
cd "$root"
.venv/bin/ruff check oracle raster_models metrics scenes reports tests raster_oracle setup.py
.venv/bin/ruff format --check oracle raster_models metrics scenes reports tests raster_oracle setup.py
exec .venv/bin/python -m pytest "$@"
