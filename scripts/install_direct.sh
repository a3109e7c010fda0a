#!/usr/bin/env bash
# Install the optional direct-solver backends of solver="direct" (docs/large_problems.md):
#   PARDISO (pypardiso, MKL wheels: pip only), CHOLMOD (scikit-sparse 0.4.16 against Debian's
#   SuiteSparse 5 + OpenBLAS) and MUMPS (python-mumps built against Debian's sequential MUMPS).
# Idempotent; each backend that cannot be installed is reported ("<name> not installed: reason")
# and skipped (its tests then skip, SuperLU stays available); always exits 0.
# Usage: scripts/install_direct.sh [PYTHON]   (default: python on PATH)
set -u
PY="${1:-python}"
say() { echo "install_direct: $*"; }
t0=$(date +%s)
"$PY" -m pip install -q "pypardiso>=0.4" >/dev/null 2>&1 && say "pardiso: installed" \
    || say "pardiso not installed: pip install pypardiso failed"
have_apt=0
if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    if apt-get install -y -q libsuitesparse-dev libopenblas0-pthread libmumps-seq-dev >/dev/null 2>&1 \
        || (apt-get update -q >/dev/null 2>&1 && \
            apt-get install -y -q libsuitesparse-dev libopenblas0-pthread libmumps-seq-dev >/dev/null 2>&1); then
        have_apt=1
    fi
fi
if [ "$have_apt" = 1 ]; then
    "$PY" -m pip install -q "scikit-sparse==0.4.16" >/dev/null 2>&1 && say "cholmod: installed" \
        || say "cholmod not installed: scikit-sparse build failed"
    "$PY" -m pip install -q "python-mumps>=0.0.4" >/dev/null 2>&1 && say "mumps: installed" \
        || say "mumps not installed: python-mumps build failed"
else
    say "cholmod, mumps not installed: need apt-get as root for SuiteSparse / MUMPS (docs/large_problems.md)"
fi
"$PY" -c "from pdlin.solvers.direct import available_direct_backends as a; print('install_direct: available', a())" 2>/dev/null || true
# which BLAS CHOLMOD resolves at run time (issue 33: it must be an optimized one, e.g.
# openblas-pthread: CHOLMOD on a reference BLAS took 303 s against 14 s at 401²)
so=$("$PY" -c "import sksparse.cholmod as m; print(m.__file__)" 2>/dev/null) && [ -n "$so" ] \
    && command -v ldd >/dev/null 2>&1 \
    && say "cholmod BLAS: $(ldd "$so" | awk '/libblas|libopenblas|libmkl|libblis/ {print $3}' \
        | xargs -r readlink -f | tr '\n' ' ')"
say "done in $(( $(date +%s) - t0 )) s"
exit 0
