"""What every benchmark prints about the machine it ran on, and wall + CPU timing.

A timing on a shared machine means little without its context: the load average (other
processes competing for the cores), the cores this process may use, the BLAS and its
threads, pdlin's thread setting and the direct backend each "direct" column really used
(``'auto'`` picks CHOLMOD or PARDISO when they are installed).  Every script in
``benchmarks/`` calls :func:`header` at the start of ``main``; timing columns show CPU
seconds beside wall seconds (:func:`timed`); speed-ups of k threads or ranks are marked
unreliable when the load average exceeds the cores left free (:func:`speedup_flag`).
See benchmarks/README.md, "Reading a benchmark's header".
"""

from __future__ import annotations

import ctypes
import datetime
import os
import platform
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "fork_call",
    "Context",
    "Timing",
    "backend_label",
    "blas_info",
    "collect",
    "direct_backends_line",
    "header",
    "load_average",
    "speedup_flag",
    "timed",
    "usable_cores",
]


def usable_cores() -> int:
    """Cores this process may run on (``os.sched_getaffinity``; ``os.cpu_count`` elsewhere)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def load_average() -> tuple[float, float, float] | None:
    """The 1-, 5- and 15-minute load averages, or None where the OS has none."""
    try:
        return os.getloadavg()
    except (AttributeError, OSError):
        return None


# -- BLAS ------------------------------------------------------------------------------------

#: thread-count getters of the BLAS builds numpy and scipy ship (the symbol names
#: threadpoolctl looks for: plain OpenBLAS, 64-bit-integer builds, scipy-openblas, MKL)
_THREAD_SYMBOLS = (
    "openblas_get_num_threads",
    "openblas_get_num_threads64_",
    "scipy_openblas_get_num_threads",
    "scipy_openblas_get_num_threads64_",
    "MKL_Get_Max_Threads",
    "bli_thread_get_num_threads",
)


def _blas_from_maps() -> list[str]:
    """BLAS libraries loaded in this process and their thread counts (Linux, no threadpoolctl)."""
    try:
        with open("/proc/self/maps") as fh:
            paths = {line.split()[-1] for line in fh if "/" in line}
    except OSError:
        return []
    out = []
    for path in sorted(paths):
        name = os.path.basename(path).lower()
        if not any(k in name for k in ("openblas", "mkl_rt", "blis", "libblas")):
            continue
        threads: Any = "?"
        try:
            lib = ctypes.CDLL(path)
            for sym in _THREAD_SYMBOLS:
                fn = getattr(lib, sym, None)
                if fn is not None:
                    fn.restype = ctypes.c_int
                    threads = int(fn())
                    break
        except OSError:
            pass
        out.append(f"{os.path.basename(path)}: {threads} thread{'' if threads == 1 else 's'}")
    return out


def blas_info() -> str:
    """The BLAS libraries numpy/scipy loaded and their thread counts, one line.

    threadpoolctl when installed; otherwise the libraries mapped into this process and
    their own thread-count functions (Linux), with numpy's build configuration for the name.
    """
    import numpy as np
    import scipy.linalg  # noqa: F401  (loads scipy's BLAS so it is reported too)

    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        threadpool_info = None
    if threadpool_info is not None:
        libs = [
            f"{d.get('internal_api')} {d.get('version')} "
            f"({os.path.basename(d.get('filepath', ''))}): {d.get('num_threads')} threads"
            for d in threadpool_info()
            if d.get("user_api") == "blas"
        ]
        if libs:
            return "; ".join(libs)
    try:
        deps = np.show_config(mode="dicts")["Build Dependencies"]["blas"]  # numpy >= 1.26
        name = f"numpy built with {deps.get('name')} {deps.get('version')}"
    except Exception:  # older numpy: no dict mode
        name = "numpy BLAS: see numpy.show_config()"
    libs = _blas_from_maps()
    env = {
        k: os.environ[k]
        for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
        if k in os.environ
    }
    return "; ".join([name, *(libs or ["threads: unknown (pip install threadpoolctl)"])]) + (
        f"; env {env}" if env else ""
    )


# -- pdlin -----------------------------------------------------------------------------------


def direct_backends_line() -> str:
    """Installed direct backends and what ``direct_backend='auto'`` picks at pdlin's threads."""
    try:
        from pdlin.solvers.direct import AUTO_MIN, auto_chain, available_direct_backends
    except ImportError as exc:
        return f"unknown ({exc})"
    avail = available_direct_backends()
    have = [b for b, ok in avail.items() if ok]
    missing = [b for b, ok in avail.items() if not ok]
    text = f"installed {', '.join(have)}" + (f" (not: {', '.join(missing)})" if missing else "")
    try:  # the selection may change (issue 33): report it, never fail the benchmark on it
        sym2, sym3 = auto_chain(True, AUTO_MIN, 2)[0], auto_chain(True, AUTO_MIN, 3)[0]
        unsym = auto_chain(False, AUTO_MIN)[0]
        text += (
            f"; 'auto' at >= {AUTO_MIN} unknowns: symmetric -> {sym2} (3D blocks: {sym3}), "
            f"nonsymmetric -> {unsym}"
        )
    except Exception as exc:  # pragma: no cover - depends on the installed pdlin
        text += f"; 'auto' selection unknown ({type(exc).__name__})"
    return text


def backend_label(info: Any, default: str = "?") -> str:
    """The direct backend a solve used, from a result, its ``info`` dict or a solver object.

    Looks for ``direct_backend`` (``solve_linear``'s info), ``backend`` (``DirectSolver``)
    or ``info['direct_backend']`` / ``solver_info['direct_backend']`` one level down.
    """
    if info is None:
        return default
    if isinstance(info, dict):
        if info.get("direct_backend"):
            return str(info["direct_backend"])
        for key in ("info", "solver_info", "linear_info"):
            sub = info.get(key)
            if isinstance(sub, dict) and sub.get("direct_backend"):
                return str(sub["direct_backend"])
        return default
    for attr in ("direct_backend", "backend"):
        val = getattr(info, attr, None)
        if isinstance(val, str) and val:
            return val
    for attr in ("info", "solver_info"):
        sub = getattr(info, attr, None)
        if isinstance(sub, dict):
            return backend_label(sub, default)
    return default


# -- header ----------------------------------------------------------------------------------


@dataclass
class Context:
    """The machine state a benchmark started under (see :func:`collect`)."""

    date: str
    python: str
    numpy: str
    scipy: str
    pdlin: str
    load: tuple[float, float, float] | None
    cores: int
    cpu_count: int
    blas: str
    pdlin_threads: str
    direct: str
    extra: dict[str, str] = field(default_factory=dict)

    @property
    def load1(self) -> float | None:
        """The 1-minute load average at the start."""
        return None if self.load is None else self.load[0]

    def lines(self) -> list[str]:
        """The header, one ``# key: value`` line each."""
        load = "unavailable" if self.load is None else " ".join(f"{x:.2f}" for x in self.load)
        rows = [
            ("date", self.date),
            ("host", f"{platform.node()} {platform.machine()}, {platform.platform(terse=True)}"),
            (
                "versions",
                f"python {self.python}, numpy {self.numpy}, scipy {self.scipy}, pdlin {self.pdlin}",
            ),
            ("load average", f"{load} (1/5/15 min)"),
            ("usable cores", f"{self.cores} (sched_getaffinity; {self.cpu_count} in the machine)"),
            ("BLAS", self.blas),
            ("pdlin threads", self.pdlin_threads),
            ("direct backends", self.direct),
            *self.extra.items(),
        ]
        return [f"# {k}: {v}" for k, v in rows]


def collect(**extra: Any) -> Context:
    """Gather the context: date, versions, load, cores, BLAS, pdlin threads, direct backends."""
    import numpy as np
    import scipy

    try:
        import pdlin
        from pdlin._threads import _n_threads

        pdlin_version = getattr(pdlin, "__version__", "?")
        threads = str(pdlin.get_num_threads())
        env = os.environ.get("PDLIN_NUM_THREADS")
        if _n_threads is not None:
            threads += " (pdlin.set_num_threads)"
        else:
            threads += f" (PDLIN_NUM_THREADS={env})" if env else " (default: the usable cores)"
    except ImportError:  # pragma: no cover
        pdlin_version, threads = "not importable", "?"
    return Context(
        date=datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"),
        python=platform.python_version(),
        numpy=np.__version__,
        scipy=scipy.__version__,
        pdlin=pdlin_version,
        load=load_average(),
        cores=usable_cores(),
        cpu_count=os.cpu_count() or 1,
        blas=blas_info(),
        pdlin_threads=threads,
        direct=direct_backends_line(),
        extra={str(k): str(v) for k, v in extra.items()},
    )


def header(file: Any = None, **extra: Any) -> Context:
    """Print the context header (``#`` lines) and return it; ``extra`` adds lines.

    Call at the start of a benchmark's ``main``; keep the returned context for
    :func:`speedup_flag` (its load average is the one before the benchmark loaded the machine).
    """
    ctx = collect(**extra)
    print("\n".join(ctx.lines()), file=file or sys.stdout, flush=True)
    return ctx


# -- timing ----------------------------------------------------------------------------------


@dataclass
class Timing:
    """Wall and CPU seconds of a :func:`timed` block (CPU: all threads, waited-for children)."""

    wall: float = 0.0
    cpu: float = 0.0

    @property
    def cores_busy(self) -> float:
        """CPU / wall: the cores the block kept busy on average."""
        return self.cpu / self.wall if self.wall > 0 else 0.0

    def __str__(self) -> str:
        return f"{self.wall:.3g} s wall, {self.cpu:.3g} s CPU"


@contextmanager
def timed() -> Iterator[Timing]:
    """Time a block: ``with timed() as t: ...`` then ``t.wall``, ``t.cpu`` (seconds).

    CPU is ``time.process_time`` (this process, every thread) plus the user + system time
    of children that ended and were waited for during the block (``os.times``), so
    forked workers count.  CPU > wall means several cores worked; CPU << wall on a busy
    machine means the process waited for a core (or for I/O).
    """
    t = Timing()
    c0, k0, w0 = time.process_time(), os.times(), time.perf_counter()
    try:
        yield t
    finally:
        w1, c1, k1 = time.perf_counter(), time.process_time(), os.times()
        t.wall = w1 - w0
        t.cpu = (
            (c1 - c0)
            + (k1.children_user - k0.children_user)
            + (k1.children_system - k0.children_system)
        )


# -- speed-ups -------------------------------------------------------------------------------


def speedup_flag(k: int, load: float | None = None, cores: int | None = None) -> str:
    """``''`` or ``'unreliable (load L > free cores F)'`` for a speed-up measured with k workers.

    A speed-up of k threads or ranks needs k idle cores: it is marked unreliable when the
    load average (other processes wanting a core) exceeds the cores the measurement left
    free, ``usable cores - k``.  ``load`` defaults to the 1-minute load average now; pass
    the header's ``ctx.load1`` for the load before the benchmark itself ran.

    Examples
    --------
    >>> speedup_flag(2, load=0.5, cores=8)
    ''
    >>> speedup_flag(2, load=1.2, cores=2)
    'unreliable (load 1.20 > free cores 0)'
    >>> speedup_flag(4, load=0.0, cores=2)
    'unreliable (4 workers > 2 usable cores)'
    """
    if load is None:
        la = load_average()
        if la is None:
            return ""
        load = la[0]
    n = usable_cores() if cores is None else cores
    if k > n:
        return f"unreliable ({k} workers > {n} usable cores)"
    free = n - k
    if load > free:
        return f"unreliable (load {load:.2f} > free cores {free})"
    return ""


def _fork_child(conn: Any, fn: Any, args: tuple[Any, ...], kw: dict[str, Any]) -> None:
    try:
        conn.send(("ok", fn(*args, **kw)))
    except Exception as exc:  # noqa: BLE001 - report any failure as a table row
        import traceback
        from pathlib import Path

        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" (at {Path(last.filename).name}:{last.lineno})"
        conn.send(("error", f"{type(exc).__name__}: {str(exc)[:160]}{where}"))
    conn.close()


def fork_call(fn: Any, *args: Any, **kw: Any) -> Any:
    """Run ``fn(*args, **kw)`` in a forked child (its own peak RSS); errors come back as str.

    The error string names the exception, its message and the line that raised it.
    """
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_fork_child, args=(child, fn, args, kw))
    proc.start()
    child.close()
    try:
        status, value = parent.recv()
    except EOFError:
        status, value = "error", f"child died (exit code {proc.exitcode})"
    proc.join()
    return value if status == "ok" else str(value)
