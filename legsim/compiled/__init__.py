"""The compiled path: the relaxed loop (``legsim.relaxed``) compiled once by numba, calling each
model's compiled functions by address (``kernel``, ``native``), with legsim's own cache of
compiled code (``cache``).

Importing this package registers the kernel with the relaxed driver; the core never imports it.
A run whose modes and controller are all written as compiled model functions
(``model_function``) runs in the kernel; any other runs the same loop interpreted, and its
execution says so (``counters["python_steps"]``, ``settings["python_reason"]``).
"""

from . import kernel  # noqa: F401 -- importing it registers the kernel with the relaxed driver
from .cache import cache_dir, clear
from .functions import model_function

__all__ = ["cache_dir", "clear", "model_function"]
