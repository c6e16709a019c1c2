"""Time symbolic derivations: chaplygin against sympy.physics.mechanics.KanesMethod.

Run from the repository root::

    .venv/bin/python benchmarks/derive.py            # best of 7, SymPy cache cleared each repeat
    .venv/bin/python benchmarks/derive.py --repeat 3 --warm-cache
    .venv/bin/python benchmarks/derive.py --profile  # also cProfile chaplygin's disk derivation
    .venv/bin/python benchmarks/derive.py --src /path/to/other/checkout/src

Every repeat builds everything anew (the System, the frames and bodies, ...) and, unless
``--warm-cache`` is given, first clears SymPy's global cache, so that no repeat profits
from the work of an earlier one (a fresh Python process starts with an empty cache too).
The time of a task is the best (minimum) over the repeats, measured with
``time.perf_counter``.  A task that runs past ``--task-timeout`` seconds is abandoned
(reported as ``>N s``).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import platform
import pstats
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import sympy as sp
from sympy.core.cache import clear_cache

ROOT = Path(__file__).resolve().parent.parent
_SRC = ROOT / "src"
if "--src" in sys.argv[:-1]:  # time another checkout of chaplygin (e.g. a git worktree)
    _SRC = Path(sys.argv[sys.argv.index("--src") + 1]).resolve()
sys.path.insert(0, str(_SRC))  # this working tree by default, also when not installed

import peer_rolling_disk

import chaplygin
from chaplygin import examples


# --------------------------------------------------------------------------- tasks
def chaplygin_task(build: Callable[[], chaplygin.System], accelerations: bool) -> Callable[[], object]:
    """Construct the system, derive the Chetaev and Chaplygin equations, read M and F
    (and, with ``accelerations``, the solved accelerations of both models)."""

    def run() -> object:
        system = build()
        chetaev = system.equations("chetaev")
        chap = system.equations("chaplygin")
        out = [chetaev.mass_matrix, chetaev.forcing, chap.mass_matrix, chap.forcing]
        assert out[0].shape == (system.n + system.g,) * 2 and out[2].shape == (system.epsilon,) * 2
        if accelerations:
            out += [chetaev.accelerations, chap.accelerations]
        return out

    return run


def kane_disk(rhs: bool) -> object:
    """The rolling disk derived from scratch with KanesMethod (``peer_rolling_disk.kane_disk``):
    the full mass matrix and forcing, and with ``rhs`` the solved ``rhs()``."""
    km = peer_rolling_disk.kane_disk(rhs=False)[0]
    out = [km.mass_matrix_full, km.forcing_full]
    assert out[0].shape == (10, 10)
    if rhs:
        out.append(km.rhs())
    return out


TASKS: dict[str, Callable[[], object]] = {
    "sphere: chaplygin  (eqs, M/F)": chaplygin_task(examples.rolling_sphere, False),
    "sphere: chaplygin  (eqs, M/F, accelerations)": chaplygin_task(examples.rolling_sphere, True),
    "disk:   chaplygin  (eqs, M/F)": chaplygin_task(examples.rolling_disk, False),
    "disk:   chaplygin  (eqs, M/F, accelerations)": chaplygin_task(examples.rolling_disk, True),
    "disk:   KanesMethod (M/F full)": lambda: kane_disk(False),
    "disk:   KanesMethod (M/F full, rhs())": lambda: kane_disk(True),
}
RATIOS = [
    (
        "KanesMethod / chaplygin, disk, equations (M, F)",
        "disk:   KanesMethod (M/F full)",
        "disk:   chaplygin  (eqs, M/F)",
    ),
    (
        "KanesMethod / chaplygin, disk, solved accelerations",
        "disk:   KanesMethod (M/F full, rhs())",
        "disk:   chaplygin  (eqs, M/F, accelerations)",
    ),
]


# --------------------------------------------------------------------------- timing
class _Timeout(Exception):
    pass


def _alarm(signum: int, frame: object) -> None:
    raise _Timeout


def measure(task: Callable[[], object], repeat: int, cold: bool, timeout: int) -> list[float] | None:
    """Times of ``repeat`` fresh runs, or None when one ran past ``timeout`` seconds."""
    times = []
    for _ in range(repeat):
        if cold:
            clear_cache()
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(timeout)
        try:
            start = time.perf_counter()
            task()
            times.append(time.perf_counter() - start)
        except _Timeout:
            return None
        finally:
            signal.alarm(0)
    return times


def machine() -> list[str]:
    model = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        rev = subprocess.run(
            ["git", "-C", str(_SRC), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(_SRC), "status", "--porcelain", "."], capture_output=True, text=True, check=True
        ).stdout.strip()
        rev = f"git {rev}" + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        rev = "no git checkout"
    return [
        f"cpu: {model}, {os.cpu_count()} logical CPUs (nproc)",
        f"python {platform.python_version()}, sympy {sp.__version__}, chaplygin {chaplygin.__version__} "
        f"from {Path(chaplygin.__file__).parent} ({rev})",
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="repeats per task (best is reported)")
    parser.add_argument("--warm-cache", action="store_true", help="do not clear SymPy's cache")
    parser.add_argument("--task-timeout", type=int, default=300, help="seconds per run of a task")
    parser.add_argument(
        "--src",
        default=str(ROOT / "src"),
        help="directory holding the chaplygin package to time (default: ./src)",
    )
    parser.add_argument(
        "--profile", action="store_true", help="cProfile one cold run of chaplygin's disk derivation"
    )
    args = parser.parse_args()

    # imports and one untimed run of each, so that module loading is not timed
    for task in TASKS.values():
        measure(task, 1, True, args.task_timeout)
    print("\n".join(machine()))
    print(f"best of {args.repeat}, SymPy cache {'kept' if args.warm_cache else 'cleared'} before each run\n")
    best: dict[str, float | None] = {}
    width = max(map(len, TASKS))
    print(f"{'task':{width}}  {'best [s]':>9}  {'median [s]':>10}")
    for name, task in TASKS.items():
        times = measure(task, args.repeat, not args.warm_cache, args.task_timeout)
        if times is None:
            best[name] = None
            print(f"{name:{width}}  {'>' + str(args.task_timeout):>9}  {'(timed out)':>10}")
        else:
            best[name] = min(times)
            print(f"{name:{width}}  {min(times):9.3f}  {statistics.median(times):10.3f}")
    print()
    for label, num, den in RATIOS:
        if best[num] is None or best[den] is None:
            print(f"{label}: n/a (a task timed out)")
        else:
            ratio = best[num] / best[den]
            verdict = "chaplygin faster" if ratio >= 1 else "chaplygin SLOWER"
            print(f"{label}: {ratio:.2f}  ({verdict})")

    if args.profile:
        clear_cache()
        prof = cProfile.Profile()
        prof.enable()
        TASKS["disk:   chaplygin  (eqs, M/F)"]()
        prof.disable()
        buf = io.StringIO()
        stats = pstats.Stats(prof, stream=buf).sort_stats("cumulative")
        stats.print_stats(r"chaplygin/", 25)
        print("\ncProfile, one cold run of 'disk: chaplygin (eqs, M/F)', chaplygin's own functions:")
        print(buf.getvalue())


if __name__ == "__main__":
    main()
