"""The stress cases, one module per family of hard cases (the ``GROUPS``). Importing this
package registers every case in ``CASES``; within a group, ``select`` keeps the order in which
its module registers them."""

# In group order, so that ``CASES`` itself (which ``legsim stress`` lists when a selection
# matches nothing) reads in the order of the table.
from . import zeno, continuation, grazing, simultaneous, resting, extremes  # noqa: I001

__all__ = ["continuation", "extremes", "grazing", "resting", "simultaneous", "zeno"]
