"""What ``chaplygin derive`` prints, and how fast: sizes, longest lines, cold times (issue 28).

Run from the repository root::

    .venv/bin/python benchmarks/readable.py                          # this working tree
    .venv/bin/python benchmarks/readable.py --baseline OLD/src       # and another checkout beside it
    .venv/bin/python benchmarks/readable.py --repeat 3 --json out.json

Every system is derived by a whole ``chaplygin derive FILE`` process with a cold cache (a fresh
``CHAPLYGIN_CACHE``: loading, derivation, tidying and printing all counted), median of
``--repeat`` wall times: every system of ``benchmarks/systems``, written by hand as a user
would (for issue 28: a sleigh on an incline with its constraint solved with ``tan`` and written
implicitly, a roller racer, a snakeboard whose wheel angle has a spring, a car with a trailer),
``derive --simplify`` of each, and every built-in example.  With ``--baseline`` the same commands run on another checkout's
``src`` (e.g. ``git worktree add /tmp/old a11bdc0``) and the table shows both and their ratio.
The issue's goals are checked at the end against this tree's numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SYSTEMS = ROOT / "benchmarks" / "systems"
HANDWRITTEN = sorted(p.stem for p in SYSTEMS.glob("*.toml"))  #: the systems written by hand
#: the goals of issue 28, item 1
ROLLER_BEFORE = 117_000
ROLLER_SECONDS = 3.0
SIMPLIFY_SECONDS = 10.0
INCLINE_RATIO = 1.2
SPRING = "-100*(phi - 1/2)"


#: seconds after which a command is stopped and its time shown as "> LIMIT" (the roller racer's
#: --simplify did not finish in 10 minutes before issue 28)
LIMIT = 120.0


def run(src: Path, args: list[str], repeat: int) -> tuple[str, float]:
    """``chaplygin ARGS`` on ``src``'s package, each repeat with an empty cache: (stdout, median s);
    a command still running after :data:`LIMIT` seconds is stopped: ("", inf)."""
    code = f"import sys; sys.path.insert(0, {str(src)!r}); from chaplygin.apps.cli import main; main()"
    times, out = [], ""
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "CHAPLYGIN_CACHE": cache, "COLUMNS": "200"}
            start = time.perf_counter()
            try:
                done = subprocess.run(
                    [sys.executable, "-c", code, *args],
                    capture_output=True,
                    text=True,
                    env=env,
                    timeout=LIMIT,
                )
            except subprocess.TimeoutExpired:
                return "", float("inf")
            times.append(time.perf_counter() - start)
        if done.returncode != 0:
            raise SystemExit(f"chaplygin {' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
        out = done.stdout
    return out, statistics.median(times)


def examples(src: Path) -> list[str]:
    out, _ = run(src, ["examples", "list"], 1)
    return re.findall(r"^(\S+)\s", out, re.M)


def measure(src: Path, repeat: int) -> dict[str, dict[str, float | str]]:
    cases = [(name, str(SYSTEMS / f"{name}.toml")) for name in HANDWRITTEN]
    cases += [(name, f"example:{name}") for name in examples(src)]
    rows: dict[str, dict[str, float | str]] = {}
    for name, spec in cases:
        text, seconds = run(src, ["derive", spec], repeat)
        row: dict[str, float | str] = {
            "bytes": len(text.encode()),
            "longest line": max(map(len, text.splitlines()), default=0),
            "cold s": seconds,
            "text": text,
        }
        if name in HANDWRITTEN:
            _, row["simplify s"] = run(src, ["derive", "--simplify", spec], 1)
        rows[name] = row
        print(f"  {name}: {row['bytes']} B, {seconds:.2f} s", file=sys.stderr)
    return rows


def table(now: dict, before: dict | None) -> str:
    head = f"{'system':<26}{'bytes':>9}{'longest':>9}{'cold [s]':>10}{'simplify [s]':>14}"
    if before:
        head += f"{'bytes before':>14}{'ratio':>7}{'cold before':>13}"
    lines = [head]
    for name, row in now.items():
        simp = "-" if "simplify s" not in row else f"{row['simplify s']:.2f}".replace("inf", f"> {LIMIT:.0f}")
        line = f"{name:<26}{row['bytes']:>9}{row['longest line']:>9}{row['cold s']:>10.2f}{simp:>14}"
        if before and name in before:
            old = before[name]
            ratio = f"{row['bytes'] / old['bytes']:.2f}" if old["bytes"] else "-"
            line += f"{old['bytes']:>14}{ratio:>7}{old['cold s']:>13.2f}"
        lines.append(line)
    return "\n".join(lines)


def goals(now: dict) -> list[tuple[str, bool]]:
    racer, tan, implicit = now["roller_racer"], now["sleigh_incline_tan"], now["sleigh_incline_implicit"]
    spring = re.search(r"^\s*phi'' = (.*)$", str(now["snakeboard_spring"]["text"]), re.M)
    ratio = max(tan["bytes"], implicit["bytes"]) / min(tan["bytes"], implicit["bytes"])
    return [
        (
            f"roller racer: {racer['bytes']} B <= {ROLLER_BEFORE // 10} B",
            racer["bytes"] <= ROLLER_BEFORE / 10,
        ),
        (
            f"roller racer: {racer['cold s']:.2f} s cold <= {ROLLER_SECONDS} s",
            racer["cold s"] <= ROLLER_SECONDS,
        ),
        (f"sleigh on an incline, tan vs implicit: {ratio:.2f}x <= {INCLINE_RATIO}x", ratio <= INCLINE_RATIO),
        (
            f"snakeboard: phi'' = {spring.group(1) if spring else '?'} (as short as {SPRING})",
            spring is not None and len(spring.group(1)) <= len(SPRING),
        ),
        *(
            (
                f"{name}: --simplify {now[name]['simplify s']:.2f} s <= {SIMPLIFY_SECONDS} s",
                now[name]["simplify s"] <= SIMPLIFY_SECONDS,
            )
            for name in HANDWRITTEN
        ),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="another checkout's src folder, run beside this one")
    parser.add_argument("--repeat", type=int, default=3, help="cold runs per system (median)")
    parser.add_argument("--json", type=Path, help="write the numbers here")
    args = parser.parse_args()
    print(
        f"{platform.node()}: {os.cpu_count()} CPUs, Python {platform.python_version()}; load {os.getloadavg()}"
    )
    now = measure(ROOT / "src", args.repeat)
    before = measure(args.baseline, args.repeat) if args.baseline else None
    if args.json:
        strip = lambda rows: {k: {f: v for f, v in r.items() if f != "text"} for k, r in rows.items()}  # noqa: E731
        args.json.write_text(json.dumps({"now": strip(now), "before": before and strip(before)}, indent=1))
    print(table(now, before))
    if before:
        shared = [n for n in now if n in before and n not in HANDWRITTEN]
        failed = [n for n in shared if not before[n]["bytes"]]  # printed nothing: it failed
        longer = [n for n in shared if now[n]["bytes"] > before[n]["bytes"] and n not in failed]
        print(
            f"\nbuilt-in examples: {len(shared) - len(longer) - len(failed)} of {len(shared)} no longer "
            "than before"
            + (f"; longer: {', '.join(longer)}" if longer else "")
            + (f"; printed nothing before: {', '.join(failed)}" if failed else "")
        )
    print("\ngoals (issue 28):")
    results = goals(now)
    for text, ok in results:
        print(f"  {'met ' if ok else 'MISS'} {text}")
    sys.exit(0 if all(ok for _, ok in results) else 1)


if __name__ == "__main__":
    main()
