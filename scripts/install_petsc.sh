#!/usr/bin/env bash
# Install PETSc + petsc4py (+ mpi4py) for pdlin's PETSc backend (backend="petsc").
#
# Idempotent: does nothing when petsc4py already imports in the target Python.
# Strategy (fastest that works on a fresh machine, see docs/petsc.md):
#   1. petsc4py already importable             -> done
#   2. Debian/Ubuntu with apt and root         -> apt-get install libpetsc-real-dev (PETSc 3.18 with
#      MUMPS, hypre, SuperLU_DIST; OpenMPI) and build petsc4py 3.18 from its PyPI sdist against it
#      (pre-generated C source: no Cython needed; builds against numpy 2); with --mpi4py also
#      mpi4py against the same OpenMPI (pdlin itself does not need it)
#   3. otherwise                               -> print "PETSc not installed: <reason>" and exit 0
#      (a source build of PETSc, `pip install petsc petsc4py`, takes ~1 h on 2 cores: do it by hand)
#
# Usage: scripts/install_petsc.sh [--mpi4py] [PYTHON]   (default: python on PATH)
set -u
WITH_MPI4PY=0
if [ "${1:-}" = "--mpi4py" ]; then WITH_MPI4PY=1; shift; fi
PY="${1:-python}"
t0=$(date +%s)
say() { echo "install_petsc: $*"; }
skip() { say "PETSc not installed: $*"; exit 0; }

if "$PY" -c "import petsc4py; petsc4py.init([]); from petsc4py import PETSc" 2>/dev/null; then
    say "petsc4py already installed: $("$PY" -c 'import petsc4py; print(petsc4py.__version__)')"
    exit 0
fi

command -v apt-get >/dev/null 2>&1 || skip "no apt-get (not Debian/Ubuntu); see docs/petsc.md for conda-forge or a source build"
[ "$(id -u)" = 0 ] || skip "apt-get needs root; run as root or see docs/petsc.md"

PETSC_VER=3.18
PETSC_DIR_DEB=/usr/lib/petscdir/petsc${PETSC_VER}/x86_64-linux-gnu-real
if [ ! -d "$PETSC_DIR_DEB/include" ]; then
    say "apt-get install libpetsc-real${PETSC_VER}-dev (PETSc ${PETSC_VER}, OpenMPI, MUMPS, hypre)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null 2>&1 || say "apt-get update failed (trying the cached lists)"
    apt-get install -y -qq --no-install-recommends "libpetsc-real${PETSC_VER}-dev" >/tmp/install_petsc_apt.log 2>&1 \
        || skip "apt-get install libpetsc-real${PETSC_VER}-dev failed (log: /tmp/install_petsc_apt.log)"
fi
[ -d "$PETSC_DIR_DEB/include" ] || skip "PETSc headers not found under $PETSC_DIR_DEB"
command -v mpicc >/dev/null 2>&1 || skip "mpicc not found after installing libpetsc-real-dev"

say "building petsc4py ${PETSC_VER} against $PETSC_DIR_DEB (a few minutes)"
"$PY" -m pip install -q numpy "setuptools<70" wheel >/dev/null 2>&1 || true
PETSC_DIR="$PETSC_DIR_DEB" PETSC_ARCH="" "$PY" -m pip install -q --no-build-isolation \
    "petsc4py==${PETSC_VER}.*" >/tmp/install_petsc_pip.log 2>&1 \
    || skip "pip could not build petsc4py ${PETSC_VER} (log: /tmp/install_petsc_pip.log)"

if [ "$WITH_MPI4PY" = 1 ]; then
    say "building mpi4py against $(mpicc -showme:version 2>/dev/null | head -1 || echo mpicc)"
    MPICC=mpicc "$PY" -m pip install -q --no-binary mpi4py mpi4py >>/tmp/install_petsc_pip.log 2>&1 \
        || say "mpi4py not installed (optional; log: /tmp/install_petsc_pip.log)"
fi

"$PY" -c "import petsc4py; petsc4py.init([]); from petsc4py import PETSc; \
print('install_petsc: petsc4py', petsc4py.__version__, 'PETSc', '.'.join(map(str, PETSc.Sys.getVersion())), \
'MUMPS' if PETSc.Sys.hasExternalPackage('mumps') else 'no MUMPS')" \
    || skip "petsc4py was built but does not import (log: /tmp/install_petsc_pip.log)"
say "done in $(( $(date +%s) - t0 )) s; run MPI jobs as root with OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"
