"""The disk cache of compiled models (chaplygin.numeric._modelcache), across real processes.

Each check runs fresh Python processes on a private cache folder (``$CHAPLYGIN_CACHE``)
and looks at what they did: whether a system's equations were derived (``System._equations``
is where ``system.equations`` keeps them; the disk cache never fills it) and whether the module
that derives was imported at all — never at how long they took.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

import chaplygin
from chaplygin import examples
from chaplygin.numeric import _modelcache
from subprocesses import run_json

# simulates the systems named in argv (in order), each 1 s; saves each trajectory's table to
# OUT/<name>.npy and reports whether it derived, and whether the deriving module was imported
# before the first system named after "|"
SCRIPT = """
import json, sys
import numpy as np
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols
import chaplygin
from chaplygin import examples

DISK = {"psi": 0.0, "theta": 0.3, "phi": 0.0, "x": 0.0, "y": 0.0, "psi'": 2.0, "theta'": 0.0, "phi'": 5.0}
KNIFE = {"x": 0.0, "y": 0.0, "phi": 0.2, "x'": 1.0, "phi'": 0.5}

def knife(other):
    x, y, phi = dynamicsymbols("x y phi")
    m, J = sp.symbols("m J", positive=True)
    t = dynamicsymbols._t
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2) + J / 2 * phi.diff(t) ** 2
    slope = sp.sin(phi) / (2 + sp.cos(phi)) if other else sp.tan(phi)
    return chaplygin.System([x, y, phi], T, {y.diff(t): slope * x.diff(t)}, name="skate")

def disk(name):
    s = examples.rolling_disk(m=2) if name == "disk-m2" else examples.rolling_disk()
    if name == "disk-renamed":
        s.name = "another name"
    return s

out, report, before = sys.argv[1], {}, None
for name in sys.argv[2:]:
    if name == "|":
        before = "chaplygin.models.derive" in sys.modules
        continue
    if name.startswith("knife"):
        s, start, params, backend = knife(name == "knife-other"), KNIFE, {"m": 1.0, "J": 0.3}, "numpy"
    else:
        s, start, backend = disk(name), DISK, "auto"
        params = {"r": 0.5, "A": 0.0625, "C": 0.125, "g": 9.81} | ({} if name == "disk-m2" else {"m": 1.0})
    tr = chaplygin.simulate(s, "chaplygin", 1.0, start, params, samples=51, backend=backend)
    assert tr.success, tr.message
    np.save(f"{out}/{name}.npy", tr.table())
    report[name] = bool(s._equations)
print(json.dumps({"derived": report, "derive imported": before}))
"""


def _run(cache: Path, out: Path, *names: str, **env: str) -> dict:
    out.mkdir(exist_ok=True)
    return run_json(SCRIPT, [str(out), *names], cache, unset=[_modelcache.ENVIRONMENT], **env)


def _same(a: Path, b: Path, *names: str) -> bool:
    return all(np.array_equal(np.load(a / f"{n}.npy"), np.load(b / f"{n}.npy")) for n in names)


def test_a_second_process_derives_nothing_and_a_changed_system_misses(tmp_path):
    cache = tmp_path / "cache"
    cold = _run(cache, tmp_path / "cold", "disk", "knife", "|", PYTHONHASHSEED="1")
    assert cold["derived"] == {"disk": True, "knife": True}
    # another process, another hash seed: the same systems (one renamed) load what the first
    # compiled, without importing the module that derives, and integrate bit for bit the same
    warm = _run(
        cache, tmp_path / "warm", "disk-renamed", "knife", "|", "disk-m2", "knife-other", PYTHONHASHSEED="2"
    )
    assert warm["derive imported"] is False
    assert warm["derived"] == {"disk-renamed": False, "knife": False, "disk-m2": True, "knife-other": True}
    assert np.array_equal(np.load(tmp_path / "cold/disk.npy"), np.load(tmp_path / "warm/disk-renamed.npy"))
    assert _same(tmp_path / "cold", tmp_path / "warm", "knife")
    # (the other constraint is another motion, which an entry of the first would not give)
    assert not np.array_equal(
        np.load(tmp_path / "warm/knife.npy"), np.load(tmp_path / "warm/knife-other.npy")
    )


def test_a_damaged_entry_is_a_miss_and_is_rewritten(tmp_path):
    cache = tmp_path / "cache"
    _run(cache, tmp_path / "cold", "disk", "knife")
    entries = {p: p.read_bytes() for p in (cache / "derivations").glob("*.json")}
    assert len(entries) == 4  # each system's compiled model and pole functions
    for path, raw in entries.items():
        path.write_bytes(raw[: len(raw) // 2])
    again = _run(cache, tmp_path / "again", "disk", "knife")
    assert again["derived"] == {"disk": True, "knife": True}
    assert _same(tmp_path / "cold", tmp_path / "again", "disk", "knife")
    assert {p: p.read_bytes() for p in (cache / "derivations").glob("*.json")} == entries
    assert _run(cache, tmp_path / "warm", "disk", "knife")["derived"] == {"disk": False, "knife": False}


def test_the_switch_turns_it_off(tmp_path):
    cache = tmp_path / "cache"
    off = {_modelcache.ENVIRONMENT: "off"}
    assert _run(cache, tmp_path / "a", "knife", **off)["derived"] == {"knife": True}
    assert not (cache / "derivations").exists()
    assert _run(cache, tmp_path / "b", "knife", **off)["derived"] == {"knife": True}


def test_the_definition_key():
    """Equal definitions share a key whatever their name; any change, or a Dummy, has another."""
    disk = examples.rolling_disk()
    renamed = examples.rolling_disk()
    renamed.name = "another"
    keys = {_modelcache.definition(s) for s in (disk, renamed)}
    assert len(keys) == 1 and None not in keys
    x, y, phi = dynamicsymbols("x y phi")
    t = dynamicsymbols._t
    m = sp.Symbol("m", positive=True)
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2) + phi.diff(t) ** 2 / 2

    def skate(**changes: object) -> chaplygin.System:
        given: dict = {"kinetic_energy": T, "constraints": {y.diff(t): sp.tan(phi) * x.diff(t)}} | changes
        return chaplygin.System([x, y, phi], **given)

    variants = [
        skate(),
        skate(kinetic_energy=T.subs(m, 2)),
        skate(kinetic_energy=T.subs(m, sp.Symbol("m"))),  # the same name without the assumption
        skate(constraints={y.diff(t): sp.sin(phi) * x.diff(t)}),
        skate(constraints={x.diff(t): y.diff(t) / sp.tan(phi)}),  # another dependent coordinate
        skate(potential_energy=m * x),
        skate(forces={x: -x.diff(t)}),
    ]
    digests = [_modelcache.definition(s) for s in variants]
    assert None not in digests and len(set(digests)) == len(digests)
    assert _modelcache.definition(skate(kinetic_energy=T + sp.Dummy("k") * phi.diff(t) ** 2)) is None
