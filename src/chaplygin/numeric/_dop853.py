"""The DOP853 method's coefficients and constants, shared by every DOP853 loop.

Hairer's 8(5,3) Runge–Kutta pair with its 7th-order dense output, exactly as
SciPy's ``scipy.integrate.DOP853`` uses it (its ``dop853_coefficients`` and
step-size controller).  Three loops follow SciPy's step sequence with these
numbers: the numba kernels of :mod:`chaplygin.numeric._loop`, their C port
(:mod:`chaplygin.numeric._ckernel`) and the plain-Python stepper on lists of
the ``numpy`` backend (:mod:`chaplygin.numeric._pyloop`).  This module imports
nothing but NumPy (for :func:`tolerances`), so a warm run that integrates in
plain Python never imports SciPy.
"""

from __future__ import annotations

import sys
import warnings
from typing import Any

import numpy as np

from chaplygin.errors import ChaplyginError

__all__ = ["E3", "E5", "EPS", "A", "B", "C", "D", "StepFailure", "tolerances"]

EPS = sys.float_info.epsilon
#: the stages of a step (stage 12, the derivative at the new point, is the next step's first)
N_STAGES = 12
#: SciPy's step-size controller: the new step is ``h · min(MAX_FACTOR, max(MIN_FACTOR,
#: SAFETY · error ** ERROR_EXPONENT))`` (no growth right after a rejected step)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
#: ``-1 / (error estimator order + 1)``
ERROR_EXPONENT = -1.0 / 8.0
#: SciPy's message for a step below ``10 · spacing(t)`` (``OdeSolver.TOO_SMALL_STEP``)
TOO_SMALL_STEP = "Required step size is less than spacing between numbers."


class StepFailure(Exception):
    """A right-hand side that failed at time ``t`` inside a step (the step is not taken): what the
    Python steppers' right-hand sides raise (SciPy's and :mod:`chaplygin.numeric._pyloop`'s)."""

    def __init__(self, message: str, t: float) -> None:
        super().__init__(message)
        self.t = t


# Hairer's DOP853 coefficients (the values of SciPy's ``dop853_coefficients``):
# 12 stages, the derivative at the new point (stage 12), 3 stages for dense output.
C = (
    0.0,
    0.05260015195876773,
    0.0789002279381516,
    0.1183503419072274,
    0.2816496580927726,
    0.3333333333333333,
    0.25,
    0.3076923076923077,
    0.6512820512820513,
    0.6,
    0.8571428571428571,
    1.0,
    1.0,
    0.1,
    0.2,
    0.7777777777777778,
)
#: strictly lower-triangular A by rows, stages 1 … 15 (row s has s entries)
A_ROWS = (
    (0.05260015195876773,),
    (
        0.0197250569845379,
        0.0591751709536137,
    ),
    (
        0.02958758547680685,
        0.0,
        0.08876275643042054,
    ),
    (
        0.2413651341592667,
        0.0,
        -0.8845494793282861,
        0.924834003261792,
    ),
    (
        0.037037037037037035,
        0.0,
        0.0,
        0.17082860872947386,
        0.12546768756682242,
    ),
    (
        0.037109375,
        0.0,
        0.0,
        0.17025221101954405,
        0.06021653898045596,
        -0.017578125,
    ),
    (
        0.03709200011850479,
        0.0,
        0.0,
        0.17038392571223998,
        0.10726203044637328,
        -0.015319437748624402,
        0.008273789163814023,
    ),
    (
        0.6241109587160757,
        0.0,
        0.0,
        -3.3608926294469414,
        -0.868219346841726,
        27.59209969944671,
        20.154067550477894,
        -43.48988418106996,
    ),
    (
        0.47766253643826434,
        0.0,
        0.0,
        -2.4881146199716677,
        -0.590290826836843,
        21.230051448181193,
        15.279233632882423,
        -33.28821096898486,
        -0.020331201708508627,
    ),
    (
        -0.9371424300859873,
        0.0,
        0.0,
        5.186372428844064,
        1.0914373489967295,
        -8.149787010746927,
        -18.52006565999696,
        22.739487099350505,
        2.4936055526796523,
        -3.0467644718982196,
    ),
    (
        2.273310147516538,
        0.0,
        0.0,
        -10.53449546673725,
        -2.0008720582248625,
        -17.9589318631188,
        27.94888452941996,
        -2.8589982771350235,
        -8.87285693353063,
        12.360567175794303,
        0.6433927460157636,
    ),
    (
        0.054293734116568765,
        0.0,
        0.0,
        0.0,
        0.0,
        4.450312892752409,
        1.8915178993145003,
        -5.801203960010585,
        0.3111643669578199,
        -0.1521609496625161,
        0.20136540080403034,
        0.04471061572777259,
    ),
    (
        0.056167502283047954,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.25350021021662483,
        -0.2462390374708025,
        -0.12419142326381637,
        0.15329179827876568,
        0.00820105229563469,
        0.007567897660545699,
        -0.008298,
    ),
    (
        0.03183464816350214,
        0.0,
        0.0,
        0.0,
        0.0,
        0.028300909672366776,
        0.053541988307438566,
        -0.05492374857139099,
        0.0,
        0.0,
        -0.00010834732869724932,
        0.0003825710908356584,
        -0.00034046500868740456,
        0.1413124436746325,
    ),
    (
        -0.42889630158379194,
        0.0,
        0.0,
        0.0,
        0.0,
        -4.697621415361164,
        7.683421196062599,
        4.06898981839711,
        0.3567271874552811,
        0.0,
        0.0,
        0.0,
        -0.0013990241651590145,
        2.9475147891527724,
        -9.15095847217987,
    ),
)
#: the 8th-order weights: the row of stage 12, evaluated at the new state, as in SciPy
B = A_ROWS[N_STAGES - 1]  # A_ROWS[0] is stage 1
E3 = (
    -0.18980075407240762,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    -0.4226823213237919,
    -0.1521609496625161,
    0.20136540080403034,
    0.02265179219836082,
    0.0,
)
E5 = (
    0.01312004499419488,
    0.0,
    0.0,
    0.0,
    0.0,
    -1.2251564463762044,
    -0.4957589496572502,
    1.6643771824549864,
    -0.35032884874997366,
    0.3341791187130175,
    0.08192320648511571,
    -0.022355307863886294,
    0.0,
)
D = (
    (
        -8.428938276109013,
        0.0,
        0.0,
        0.0,
        0.0,
        0.5667149535193777,
        -3.0689499459498917,
        2.38466765651207,
        2.117034582445028,
        -0.871391583777973,
        2.2404374302607883,
        0.6315787787694688,
        -0.08899033645133331,
        18.148505520854727,
        -9.194632392478356,
        -4.436036387594894,
    ),
    (
        10.427508642579134,
        0.0,
        0.0,
        0.0,
        0.0,
        242.28349177525817,
        165.20045171727028,
        -374.5467547226902,
        -22.113666853125306,
        7.733432668472264,
        -30.674084731089398,
        -9.332130526430229,
        15.697238121770845,
        -31.139403219565178,
        -9.35292435884448,
        35.81684148639408,
    ),
    (
        19.985053242002433,
        0.0,
        0.0,
        0.0,
        0.0,
        -387.0373087493518,
        -189.17813819516758,
        527.8081592054236,
        -11.57390253995963,
        6.8812326946963,
        -1.0006050966910838,
        0.7777137798053443,
        -2.778205752353508,
        -60.19669523126412,
        84.32040550667716,
        11.99229113618279,
    ),
    (
        -25.69393346270375,
        0.0,
        0.0,
        0.0,
        0.0,
        -154.18974869023643,
        -231.5293791760455,
        357.6391179106141,
        93.40532418362432,
        -37.45832313645163,
        104.0996495089623,
        29.8402934266605,
        -43.53345659001114,
        96.32455395918828,
        -39.17726167561544,
        -149.72683625798564,
    ),
)


def _matrix(rows: tuple[tuple[float, ...], ...], width: int) -> list[list[float]]:
    out = [[0.0] * width for _ in range(len(rows) + 1)]
    for s, row in enumerate(rows, start=1):
        out[s][: len(row)] = list(row)
    return out


#: A as a 16 × 16 matrix, row s the coefficients of stage s (row 0 and the upper triangle zero)
A: list[list[float]] = _matrix(A_ROWS, 16)


def tolerances(rtol: float, atol: Any, n: int) -> tuple[float, np.ndarray]:
    """SciPy's ``validate_tol``: ``rtol`` is raised to ``100·eps``; ``atol`` scalar or ``(n,)``."""
    rtol = float(rtol)
    if rtol < 100 * EPS:
        warnings.warn(f"rtol = {rtol:g} is below 100·eps; using {100 * EPS:g} (as SciPy does).", stacklevel=3)
        rtol = 100 * EPS
    a = np.asarray(atol, dtype=float)
    if a.ndim > 0 and a.shape != (n,):
        raise ChaplyginError(f"atol: a scalar or one value per state entry ({n}), not shape {a.shape}.")
    if np.any(a < 0):
        raise ChaplyginError("atol must be non-negative.")
    return rtol, np.ascontiguousarray(np.broadcast_to(a, (n,)), dtype=float)
