"""The forced linear oscillator with a stop (paper 000, Section V-B, Fig. 14, Table I).

A mass m on a spring, with viscous damping, forced by ``u(t) = U cos(Omega t)`` (N), moves along
x and may hit a rigid stop at ``x_max``::

    x'' + 2 a x' + omega^2 x = u(t) / m          while x < x_max,
    (x, x') -> (x, -c x')                         when x reaches x_max moving towards it.

One mode ``free`` with state ``(x, xd)`` (m, m/s). With the stop there is one transition
``impact`` (``free -> free``) with guard ``max(x_max - x, -xd)``: past the guard means beyond
the stop *and* moving into it, so near an impact the guard's value is the distance to the stop
and eps is measured in metres. Without the stop there is no transition. The forcing is the
model's *control* ``u(t, x) = U cos(Omega t)``, a ``legsim.control.ControlLaw`` sampled at every
Runge-Kutta stage. Modes, guards, resets and the forcing are written once as compiled model
functions (``legsim.model``), so a run steps in the compiled kernel.

With the effect ``zeno = { window = h + eps }`` (Zeno continuation, off by default) an impact
whose next flight would be shorter than the window sticks instead of chattering: transition
``stick`` into mode ``stuck`` (state held), left through ``release`` when the free acceleration
at the stop ``F = u/m - omega^2 x_max`` changes sign, as the exact mass does (guards on
(t, x, u); see ``make_system`` and docs/stress.md).

Table I of paper 000 (m = 1):

=========  ====  ===  =======  ===============  =====  =====  =====  =====
example    a     c    t_max    u(t)             x0     xd0    x_max  omega
=========  ====  ===  =======  ===============  =====  =====  =====  =====
Example 1  0.05  0.9  40 pi    20 cos(5 t / 2)  11.36  31.4   14     2.5
Example 2  0.95  0.5  4 pi     cos(t)           -0.8   0      -0.8   1
=========  ====  ===  =======  ===============  =====  =====  =====  =====

``OscillatorReference`` is the exact execution: eq. (28) between impacts (the forcing integral
in closed form), impact times root-found on it with certified brackets, sticking phases at the
stop, and Zeno accumulations summed in closed form (see its docstring for the error made).

=================  ===========================================================================
module             responsibility
=================  ===========================================================================
``model``          ``make_system`` (the hybrid system), the forcing law, ``EXAMPLES``
``reference``      ``OscillatorReference``, the exact execution
``builder``        ``BUILDER`` for scenes: effects, picture, the run's reference
=================  ===========================================================================
"""

from .builder import BUILDER
from .model import EXAMPLES, MODE, NAMES, STUCK, forcing, make_system
from .reference import OscillatorReference

__all__ = ["BUILDER", "EXAMPLES", "MODE", "NAMES", "STUCK", "OscillatorReference", "forcing", "make_system"]
