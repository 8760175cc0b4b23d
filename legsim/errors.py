"""Exception classes of legsim.

Every error a user can provoke is one of these, with a message that names what is wrong
(the mode, transition, time, file or field), so that nobody has to read a numpy traceback.
Ordinary ends of a simulation (t_final reached, transition budget used up, halving exhausted)
are not exceptions: they are the ``status`` of the returned ``Execution``.
"""

from __future__ import annotations


class LegsimError(Exception):
    """Base class of all legsim errors."""


class ModelError(LegsimError, ValueError):
    """A hybrid system is malformed: unknown mode, wrong dimension, non-callable, bad output."""


class SimulationError(LegsimError, ValueError):
    """The arguments of a simulation are invalid (h, eps, t_final, x0, method, mode)."""


class SceneError(LegsimError, ValueError):
    """A scene file is malformed; the message names the file and the field."""


class ModelBreakdown(LegsimError):
    """Raised by a model's field, guard or reset when the model leaves its range of validity
    (a runner's body hits the ground, a leg passes through the body). The integrator ends the
    run with status ``model_breakdown`` and this message, keeping the execution computed so far,
    instead of propagating the exception."""


class OutputError(LegsimError):
    """An output file cannot be written (or would replace something it must not); the message
    names the output and the path."""


class ContractError(ModelError):
    """A model's callable returned something the contract of ``legsim.hybrid`` does not allow at
    some evaluation during a run (a guard that is not a real number, a field of the wrong shape).
    The integrator re-raises it as a ``ModelError`` naming the mode, the transition and the time."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (what ``timeout``, systemd and container runtimes send) as the command line
    raises it: a ``KeyboardInterrupt``, so that a run stops the way Ctrl-C stops it (temporary
    files removed, no output half-written), and exits with 143 = 128 + SIGTERM."""
