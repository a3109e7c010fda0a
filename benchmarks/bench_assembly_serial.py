"""One-thread CPU split of the LPS / XOSB / correspondence assembly: parallel vs serial parts.

Each call runs under cProfile with ``time.process_time`` as the clock on one thread (best
of 3, a fresh model per call).  "parallel" is the time in the numba kernels
(``pdlin/_numba_kernels.py``) and in the thread-pool chunk functions (``chunk``,
``sizes``, ``marks``, ``copy``); "serial" is the rest.  The Amdahl bound
``total / (serial + parallel / 2)`` is the 2-thread speed-up if the parallel part halves.
CPU time is insensitive to other jobs on the machine, unlike the 2-thread wall clock of
``benchmarks/bench_threads.py``.  To measure another version, put its checkout first on
``PYTHONPATH``.  The wall column is the same (profiled) call's wall time: far above its CPU
time, it says the call waited for a core (see the header's load average).

Usage: ``python benchmarks/bench_assembly_serial.py`` (~1.5 min).
"""

from __future__ import annotations

import cProfile
import os
import pstats
import sys
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pdlin  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import header, timed  # noqa: E402

PARALLEL = {"chunk", "sizes", "marks", "copy"}


def main() -> None:
    pdlin.set_num_threads(1)
    header()
    cl = pdlin.grid((30,) * 3, spacing=1 / 30)
    bl = pdlin.find_bonds(cl, ratio=3.015)
    c2 = pdlin.grid((401, 401), spacing=1 / 401)
    bn = pdlin.find_bonds(c2, ratio=2.0, influence="inverse")
    bs = pdlin.find_bonds(c2, ratio=2.0)

    def corr(control: str) -> pdlin.Correspondence:
        return pdlin.Correspondence(E=1.0, nu=0.25, control=control, plane="strain")

    rows = [
        ("LPS K (3D, 27,000 pts)", lambda: pdlin.LPS(E=1.0, nu=0.25).stiffness(cl, bl)),
        ("XOSB K (3D, 27,000 pts)", lambda: pdlin.XOSB(E=1.0, nu=0.25).stiffness(cl, bl)),
        ("correspondence K, no control (401²)", lambda: corr("none").stiffness(c2, bn)),
        ("correspondence K, stress points (401²)", lambda: corr("stress_points").stiffness(c2, bs)),
    ]
    for _, f in rows:
        f()  # numba compile / cache load
    print(f"# {pdlin.__file__}, load {os.getloadavg()[0]:.2f}\n")
    print(
        "| call | one-thread CPU (s) | wall (s) | serial (s) | parallel (s) | Amdahl 2-thread "
        "bound | top serial own times (approx.) |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, f in rows:
        best = None
        for _ in range(3):
            pr = cProfile.Profile(timer=time.process_time)
            with timed() as t:
                pr.enable()
                f()
                pr.disable()
            st = pstats.Stats(pr).stats  # type: ignore[attr-defined]

            def par(k: tuple[str, int, str]) -> bool:
                return k[0].endswith("_numba_kernels.py") or ("pdlin" in k[0] and k[2] in PARALLEL)

            total = sum(v[2] for v in st.values())
            p = sum(v[3] for k, v in st.items() if par(k))
            # own time of the serial functions (not called only from parallel ones)
            ser = [
                (v[2], k[2])
                for k, v in st.items()
                if not par(k) and not (v[4] and all(par(c) for c in v[4]))
            ]
            top = sorted(ser, reverse=True)[:4]
            if best is None or total < best[0]:
                best = (total, p, top, t.wall)
        assert best is not None
        total, p, top, wall = best
        s = total - p
        names = ", ".join(f"{n} {t:.3f}" for t, n in top)
        print(
            f"| {name} | {total:.3f} | {wall:.3f} | {s:.3f} | {p:.3f} | "
            f"{total / (s + p / 2):.2f} | {names} |"
        )


if __name__ == "__main__":
    main()
