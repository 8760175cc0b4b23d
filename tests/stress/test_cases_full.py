"""The stress suite's full form (longer horizons, more refinements, 1e3 s of running): the same
assertions as the quick form. Several minutes: LEGSIM_FULL=1 or -m slow (`legsim stress` runs it
too); tests/conftest.py skips ``slow`` tests otherwise."""

import pytest

from helpers.stress import known_failures
from legsim import stress

CASES = stress.select()


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_full_case_holds_its_invariants(case):
    result = case.run(False)
    assert result.error is None, result.error
    failing = {c.name for c in result.checks if not c.passed}
    assert not failing - known_failures(case.name), "\n".join(result.failures)
