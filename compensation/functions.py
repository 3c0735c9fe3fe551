"""The seed's algebraic compensation functions (seed §5.3, eq. 5.2 and 5.3, Fig. 5.6).

Both take the valve setpoint u_v [V] and parameters a [V] (global maximum of U_c), b [1/V] (inverse of
the valve range the compensation covers) and c [-] (horizontal shift, c = b r with r the setpoint at
zero velocity). The square root of a negative argument is taken as -sqrt(|x|), "taking the square-root
out of the absolute value and multiplying by the sign of the original expression" (seed §5.3). Both are
normalised so that a is their maximum (hence the factor 4 in (5.3)). Arrays broadcast; compiled
(numba), so the compiled compensators call the same functions.
"""

from __future__ import annotations

import numba
import numpy as np

_jit = numba.njit(cache=True)


@_jit
def signed_sqrt(x):
    """sign(x) sqrt(|x|)."""
    return np.copysign(np.sqrt(np.abs(x)), x)


@_jit
def function1(u_v, a, b, c):
    """(1): U_c = a sqrt(sin(b u_v - c)) (seed eq. 5.2); zero again at b u_v - c = ±pi."""
    return a * signed_sqrt(np.sin(b * u_v - c))


@_jit
def function2(u_v, a, b, c):
    """(2): U_c = 4 a [sqrt(b u_v - c) - (b u_v - c)] (seed eq. 5.3); maximum a at b u_v - c = 1/4, zero at 1.

    For the smooth flow area a = 300 x_v^2 (seed eq. 3.11) this is the exact static compensation shape:
    with the desired flow curve s u_v through the point u_max, U_c = u_max [sqrt(u_v/u_max) - u_v/u_max],
    i.e. a = u_max/4, b = 1/u_max (seed eq. 5.1).
    """
    x = b * u_v - c
    return 4.0 * a * (signed_sqrt(x) - x)


FUNCTIONS = {1: function1, 2: function2}
