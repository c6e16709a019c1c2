"""The work around the C ensemble's loop (issue 32, item 4): the observations at the start.

``simulate_ensemble`` observes every member at its start (energy, constraint residuals,
velocities).  It did so with one call of the C kernel per member, some 20 µs each: at 10⁵
rolling disks about 2 s, twice the 16-core loop of the issue's table.  The C kernel observes
many states with one parameter vector in one call, so members are grouped by their parameters;
the rows must be those of one call per member, the reference, exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from cases import DISK_0, DISK_P, require_c_compiler
from chaplygin import examples
from chaplygin.numeric._ckernel import CKernel
from chaplygin.numeric.codegen import compile_model, parameter_vector
from chaplygin.numeric.ensemble import _observe_all, simulate_ensemble

require_c_compiler()


@pytest.fixture(scope="module")
def disk():
    return examples.rolling_disk()


def test_grouped_observations_equal_one_call_per_member(disk):
    c = compile_model(disk, "chaplygin", "classic", "c")
    rng = np.random.default_rng(0)
    count = 40
    Y = np.tile([DISK_0[name] for name in c.layout.state], (count, 1)) + rng.normal(0, 0.1, (count, 8))
    t = rng.uniform(0, 1, count)
    base = parameter_vector(c.layout, DISK_P)
    shared = np.tile(base, (count, 1))
    three = shared.copy()  # three parameter sets, interleaved (one with a singular mass matrix)
    three[1::3, c.layout.parameters.index("m")] = 2.0
    three[2::3, [c.layout.parameters.index(k) for k in ("m", "A", "C")]] = 0.0
    distinct = shared * rng.uniform(0.5, 1.5, (count, 1))  # every member its own
    for P in (shared, three, distinct):
        expected = np.array([c.observe(ti, yi, pi) for ti, yi, pi in zip(t, Y, P)])
        np.testing.assert_array_equal(_observe_all(c, t, Y, P), expected)


def test_an_ensemble_observes_its_start_in_one_call(disk, monkeypatch):
    """40 members, one parameter set: one call of the kernel for the start, none per member (the
    end is observed inside the loop)."""
    calls = {"observe": 0, "observe_many": 0}
    for name in calls:
        original = getattr(CKernel, name)

        def counted(self, *args, _original=original, _name=name):
            calls[_name] += 1
            return _original(self, *args)

        monkeypatch.setattr(CKernel, name, counted)
    starts = [{**DISK_0, "theta": 0.1 + 0.01 * k} for k in range(40)]
    ens = simulate_ensemble(disk, "chaplygin", 0.1, starts, DISK_P, backend="c", time_limit=None)
    assert ens.success.all()
    assert calls == {"observe": 0, "observe_many": 1}


def test_numbers_for_parameters_are_one_row_seen_by_every_member(disk):
    """Parameters given as numbers make no n × k matrix for the GPU (a view of one row, which it
    uploads once); the CPU loops get a matrix they may write (numba compiles its loop again for a
    read-only array: 11.5 s against 7.7 s for a first ensemble); the ensemble is the same as with
    the same values given per member."""
    from chaplygin.numeric.ensemble import _parameter_matrix

    c = compile_model(disk, "chaplygin", "classic", "c")
    P, columns = _parameter_matrix(disk, c.layout, DISK_P, 10**6, one_row=True)
    assert P.shape == (10**6, len(c.layout.parameters)) and P.strides[0] == 0
    full = _parameter_matrix(disk, c.layout, DISK_P, 10)[0]
    assert full.flags.c_contiguous and full.flags.writeable
    np.testing.assert_array_equal(P[123], parameter_vector(c.layout, DISK_P))
    assert set(columns) == set(c.layout.parameters) and columns["m"].shape == (10**6,)
    starts = [{**DISK_0, "theta": 0.1 + 0.01 * k} for k in range(8)]
    per_member = {key: np.full(8, value) for key, value in DISK_P.items()}
    assert _parameter_matrix(disk, c.layout, per_member, 8, one_row=True)[0].strides[0] != 0
    runs = [simulate_ensemble(disk, "chaplygin", 0.5, starts, p, backend="c") for p in (DISK_P, per_member)]
    for field in ("y", "energy", "energy_initial", "constraint_residual", "rhs_evaluations"):
        np.testing.assert_array_equal(getattr(runs[0], field), getattr(runs[1], field), err_msg=field)


def test_a_block_of_members_sees_the_one_row_of_parameters():
    """``_rows``: the rows of a block (a slice, an index array) of a one-row ``P`` are that row
    seen by each of them; a full matrix is indexed as it is; no parameters stay a plain array."""
    from chaplygin.numeric.ensemble import _rows

    row = np.array([1.0, 2.0, 3.0])
    one = np.broadcast_to(row, (10, 3))
    for rows, count in ((slice(2, 5), 3), (slice(None), 10), (slice(8, 20), 2), (np.array([9, 0, 4, 4]), 4)):
        block = _rows(one, rows)
        assert block.shape == (count, 3) and (count == 0 or block.strides[0] == 0)
        np.testing.assert_array_equal(block, one[rows])
    full = np.arange(30.0).reshape(10, 3)
    np.testing.assert_array_equal(_rows(full, np.array([9, 0])), full[[9, 0]])
    bare = np.zeros((10, 0))
    assert _rows(bare, slice(2, 5)).shape == (3, 0) and _rows(bare, slice(2, 5)).flags.writeable
