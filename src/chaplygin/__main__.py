"""``python -m chaplygin demo``: the seed paper's sphere, derived and checked.

The full command line (typer + rich) arrives with the CLI work; this entry
point keeps ``make demo`` meaningful until then.
"""

from __future__ import annotations

import sys


def demo() -> int:
    """Derive, check and print the paper's §4 sphere equations."""
    from sympy.physics.vector.printing import vsstrrepr

    from . import equivalent, examples

    sphere = examples.rolling_sphere()
    print(sphere)
    print("\nReduced kinetic energy T~ (paper eq. (48)):")
    print(f"  {vsstrrepr(sphere.reduced_kinetic_energy)}")
    chetaev = sphere.equations("chetaev")
    classic = sphere.equations("chaplygin", "classic")
    new = sphere.equations("chaplygin", "new")
    for eqs in (classic, new):
        print()
        print(eqs.pretty())
    print("\nSolved accelerations (Chaplygin):")
    for acc, expr in classic.accelerations.items():
        print(f"  {vsstrrepr(acc)} = {vsstrrepr(expr)}")
    print("\nChecks against the Chetaev multiplier system (6):")
    print(f"  Chaplygin (15) vs multipliers: {equivalent(sphere, classic, chetaev)}")
    print(f"  new form (40) vs multipliers:  {equivalent(sphere, new, chetaev)}")
    print(f"  virtual work of the constraint forces under (4): {chetaev.virtual_work()}")
    print()
    print(sphere.integrability())

    from . import classify, compare_models

    lindelof = sphere.equations("lindelof", "classic")
    print("\nVakonomic model: Lindelöf's equations (22) (constraints substituted into T):")
    print(lindelof.pretty())
    print(f"\n  (22) vs the paper's new form (39): {equivalent(sphere, lindelof, sphere.equations('lindelof', 'new'))}")
    print(f"  Lindelöf (22) vs Chaplygin (15):   {equivalent(sphere, lindelof, classic)}")
    print()
    print(compare_models(sphere))
    print(f"\nClassifier on Lindelöf's equations: {classify(sphere, lindelof.equations)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args in ([], ["demo"]):
        return demo()
    print("usage: python -m chaplygin demo", file=sys.stderr)
    return 2


if __name__ == "__main__":
    raise SystemExit(main())
