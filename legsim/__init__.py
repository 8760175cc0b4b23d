"""legsim: simulation of controlled hybrid systems with the relaxed hybrid integrator.

Public API::

    from legsim import HybridSystem, Mode, Transition, simulate, Execution
    legsim.sweep(scene, grid=..., walk=..., orbit=..., out=...)   # many variations on Dask
"""

__version__ = "0.1.0"

from . import sweep  # noqa: I001 -- callable: legsim.sweep(...) runs a sweep (Dask is imported only then)
from .errors import LegsimError, ModelError, SceneError, SimulationError
from .execution import Execution, Samples, Segment, Strip, TransitionRecord
from .hybrid import Continuation, HybridSystem, Mode, Transition
from .methods import METHODS, Tableau, get_method
from .relaxed import simulate
from .model import ModeFunctions


def __getattr__(name: str) -> object:
    """``legsim.model_function``, imported with the compiled path (numba) on first use: importing
    legsim itself stays light, and the compiled path registers its kernel when it is imported."""
    if name == "model_function":
        from .compiled import model_function

        return model_function
    raise AttributeError(f"module 'legsim' has no attribute {name!r}")


__all__ = [
    "METHODS",
    "Continuation",
    "Execution",
    "HybridSystem",
    "LegsimError",
    "Mode",
    "ModeFunctions",
    "ModelError",
    "Samples",
    "SceneError",
    "Segment",
    "SimulationError",
    "Strip",
    "Tableau",
    "Transition",
    "TransitionRecord",
    "__version__",
    "get_method",
    "model_function",
    "simulate",
    "sweep",
]
