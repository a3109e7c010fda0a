#!/usr/bin/env bash
# Build the docs site with warnings as errors (what CI runs).
#   bash docs/build.sh [OUTDIR]        default OUTDIR: docs/_build/html
# Needs the docs extra: pip install ".[docs]"   (or pip install -e ".[docs]")
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-docs/_build/html}"
exec python -m sphinx -W --keep-going -b html docs "$out"
