"""Fuzz the system-file expression parser with 10⁶ inputs (on demand; tests/test_fuzz.py is the CI-sized run).

Run from the repository root::

    .venv/bin/python benchmarks/fuzz.py                      # 10**6 inputs, seed 0, all CPU cores
    .venv/bin/python benchmarks/fuzz.py --count 20000 --seed 3 --json fuzz.json

Inputs come from ``tests/fuzzgrammar.py``: half are valid expressions of the documented grammar
(numbers with huge and tiny exponents, names, velocities, functions, nesting), a tenth valid
constant expressions (read as ``[parameters]`` values are, with ``parse_constant``), the rest
mutated expressions, token soup and random characters.  Each input runs under a per-input alarm
(``--timeout``, default 1 s).  Reported: the inputs by family and outcome, and every failure —

* **crash**: an exception other than ``SystemFileError``;
* **hang**: an input still running after ``--timeout``; each is re-timed alone at the end, and
  only those still over the limit then make the run fail (a busy machine slows some inputs);
* **valid refused**: a grammatical input refused for anything but a limit or a value
  (``ParseError.kind`` other than ``"limit"``/``"value"``);
* **internal**: a ``ParseError`` of kind ``"internal"`` (SymPy/mpmath failed);
* **state**: mpmath's precision or SymPy's global parameters changed after an input, or a probe
  expression (``sign(sin(19))``…) no longer evaluates (checked every 500 inputs);

with examples of each.  The exit status is 1 when there is any failure.
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import multiprocessing
import os
import platform
import random
import signal
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))  # this working tree, also when not installed
sys.path.insert(0, str(ROOT / "tests"))

import mpmath
from sympy.core.parameters import global_parameters

import fuzzgrammar as fg
from chaplygin.io.parser import ParseError, parse_constant, parse_expression

FAILURES = ("crash", "hang", "valid refused", "internal", "state")
EXAMPLES = 5
CHUNK = 1000
PROBE_EVERY = 500


class Hang(BaseException):
    """Raised by the alarm; a BaseException, so that no ``except Exception`` in the parser catches it."""


def _on_alarm(signum: int, frame: Any) -> None:
    raise Hang


class _Source:
    def __init__(self, rng: random.Random) -> None:
        self.rng = rng

    def integer(self, lo: int, hi: int) -> int:
        return self.rng.randint(lo, hi)


def _state() -> tuple[Any, ...]:
    gp = global_parameters
    return (mpmath.mp.prec, mpmath.mp.dps, gp.evaluate, gp.distribute, gp.exp_is_pow)


def probes_fail() -> str | None:
    """None when the probe expressions evaluate as they should; else what went wrong."""
    for text, expected in fg.PROBES:
        try:
            value = parse_constant(text)
        except Exception as exc:
            return f"{text}: {type(exc).__name__}: {str(exc).splitlines()[0]}"
        if expected is not None and not math.isclose(value, expected, rel_tol=1e-12):
            return f"{text} = {value}, expected {expected}"
        if expected is None and not math.isfinite(value):
            return f"{text} = {value}"
    return None


def run_one(family: str, text: str, timeout: float) -> tuple[str, str | None]:
    """``(outcome, detail)`` for one input; outcome is ``ok``, a refusal kind, or a failure."""
    try:
        try:
            signal.setitimer(signal.ITIMER_REAL, timeout)
            if family == "constant":
                parse_constant(text)
            else:
                parse_expression(text, fg.NAMES)
        finally:  # the alarm may ring here too: the outer handler counts it
            signal.setitimer(signal.ITIMER_REAL, 0)
        outcome, detail = "ok", None
    except Hang:
        outcome, detail = "hang", None
    except ParseError as exc:
        outcome, detail = exc.kind, exc.reason
        if exc.kind == "internal":
            outcome = "internal"
        elif family in ("valid", "constant") and exc.kind not in fg.ALLOWED_FOR_VALID:
            outcome = "valid refused"
    except Exception as exc:
        outcome, detail = "crash", f"{type(exc).__name__}: {str(exc)[:200]}"
    return outcome, detail


def run_chunk(job: tuple[int, int, int, float]) -> dict[str, Any]:
    """Inputs ``[start, start + n)`` of the run with ``seed``; counts and examples of failures."""
    seed, start, n, timeout = job
    signal.signal(signal.SIGALRM, _on_alarm)
    counts: collections.Counter[str] = collections.Counter()
    examples: dict[str, list[tuple[str, str, str | None]]] = collections.defaultdict(list)
    hangs: list[tuple[str, str]] = []
    before = _state()
    for k in range(start, start + n):
        family, text = fg.draw(_Source(random.Random(f"{seed}:{k}")))
        outcome, detail = run_one(family, text, timeout)
        counts[f"{family}\t{outcome}"] += 1
        failure = outcome if outcome in FAILURES else None
        if outcome == "hang":
            hangs.append((family, text))
        if _state() != before:
            failure, detail = "state", f"{before} -> {_state()}"
            mpmath.mp.prec, mpmath.mp.dps = before[0], before[1]
        elif (k + 1) % PROBE_EVERY == 0:
            broken = probes_fail()
            if broken is not None:
                failure, detail = "state", "probe failed after this input: " + broken
        if failure is not None:
            if failure == "state":
                counts["FAIL\tstate"] += 1
            if len(examples[failure]) < EXAMPLES:
                examples[failure].append((family, text, detail))
    return {"counts": counts, "examples": examples, "hangs": hangs}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--count", type=int, default=10**6, help="number of inputs (default 10**6)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=1.0, help="seconds per input before it counts as a hang")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--json", type=Path, help="also write the report here")
    args = ap.parse_args()

    jobs = [(args.seed, s, min(CHUNK, args.count - s), args.timeout) for s in range(0, args.count, CHUNK)]
    counts: collections.Counter[str] = collections.Counter()
    examples: dict[str, list[Any]] = collections.defaultdict(list)
    hangs: list[tuple[str, str]] = []
    start = time.perf_counter()
    with multiprocessing.get_context("fork").Pool(args.workers) as pool:
        for done, result in enumerate(pool.imap_unordered(run_chunk, jobs), 1):
            counts.update(result["counts"])
            hangs.extend(result["hangs"])
            for kind, items in result["examples"].items():
                examples[kind].extend(items[: EXAMPLES - len(examples[kind])])
            if done % 50 == 0:
                print(
                    f"  {done * CHUNK} inputs, {time.perf_counter() - start:.0f} s",
                    file=sys.stderr,
                    flush=True,
                )
    wall = time.perf_counter() - start

    by_family: dict[str, collections.Counter[str]] = collections.defaultdict(collections.Counter)
    for key, n in counts.items():
        family, outcome = key.split("\t")
        if family != "FAIL":
            by_family[family][outcome] += n
    failures = {kind: sum(n for key, n in counts.items() if key.endswith("\t" + kind)) for kind in FAILURES}
    failures["state"] = counts["FAIL\tstate"]

    # an input over the limit on a busy machine may be quick alone: every one is re-timed alone
    signal.signal(signal.SIGALRM, _on_alarm)
    retimed: dict[str, tuple[float, str]] = {}
    for family, text in hangs:
        t0 = time.perf_counter()
        outcome, _ = run_one(family, text, 30.0)
        retimed[text] = (round(time.perf_counter() - t0, 2), outcome)
    confirmed = [t for t, (s, _) in retimed.items() if s > args.timeout]

    valid = sum(by_family["valid"].values()) + sum(by_family["constant"].values())
    accepted = by_family["valid"]["ok"] + by_family["constant"]["ok"]
    print(
        f"chaplygin parser fuzz: {args.count} inputs, seed {args.seed}, {args.workers} workers, "
        f"timeout {args.timeout} s per input"
    )
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
        f"wall time {wall:.0f} s ({wall / max(args.count, 1) * 1e3 * args.workers:.2f} ms per input per worker)"
    )
    print(
        f"valid inputs (grammar): {valid}, accepted {accepted}, refused for a limit "
        f"{by_family['valid']['limit'] + by_family['constant']['limit']}, for a value "
        f"{by_family['valid']['value'] + by_family['constant']['value']}"
    )
    print(
        f"other inputs: {args.count - valid}, accepted "
        f"{sum(by_family[f]['ok'] for f in ('mutated', 'soup', 'noise'))}"
    )
    print()
    outcomes = ["ok", "syntax", "name", "limit", "value", *FAILURES[:-1]]
    print(f"{'family':10}" + "".join(f"{o:>15}" for o in outcomes))
    for family in fg.FAMILIES:
        print(f"{family:10}" + "".join(f"{by_family[family][o]:>15}" for o in outcomes))
    print()
    for kind in FAILURES:
        extra = f" (over {args.timeout} s when re-run alone: {len(confirmed)})" if kind == "hang" else ""
        print(f"{kind:14} {failures[kind]}{extra}")
        for family, text, detail in examples.get(kind, []):
            extra = f"  [alone: {retimed[text][0]} s, {retimed[text][1]}]" if kind == "hang" else ""
            print(f"    {family}: {text[:300]!r}{extra}")
            if detail:
                print(f"        {detail[:300]}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "count": args.count,
                    "seed": args.seed,
                    "workers": args.workers,
                    "timeout": args.timeout,
                    "wall_s": wall,
                    "by_family": by_family,
                    "failures": failures,
                    "examples": examples,
                    "hangs_retimed": retimed,
                },
                indent=1,
            ),
            encoding="utf-8",
        )
    failures["hang"] = len(confirmed)
    return 1 if any(failures.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
