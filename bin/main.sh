#!/usr/bin/env bash
# The main job: set up if needed, then run raster-oracle on the built-in default scenes.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$root/bin/setup.sh"
exec "$root/.venv/bin/raster-oracle" main --out "${RASTER_ORACLE_OUT:-$root/out}" "$@"
