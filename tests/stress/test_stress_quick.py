"""The stress suite's quick form: every case runs and every invariant it checks holds, except
the core findings listed in conftest.CORE_FINDINGS, which must fail exactly as recorded (strict
xfail: the day the core is fixed, the entry has to go)."""

import pytest

from legsim import stress

from .conftest import CORE_FINDINGS, CORE_FINDINGS_WHY

_results: dict[str, stress.CaseResult] = {}


def result_of(case: stress.Case) -> stress.CaseResult:
    if case.name not in _results:
        _results[case.name] = case.run(True)
    return _results[case.name]


CASES = stress.select()


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_quick_case_holds_its_invariants(case):
    result = result_of(case)
    assert result.error is None, result.error + "\n" + str(result.numbers.get("traceback"))
    assert len(result.checks) >= 6, "a case checks at least the execution invariants and its own"
    failing = {c.name for c in result.checks if not c.passed}
    unexpected = failing - CORE_FINDINGS.get(case.name, set())
    assert not unexpected, "\n".join(result.failures)


def _why(name):
    return CORE_FINDINGS_WHY.get(name) or "; ".join(CORE_FINDINGS_WHY[c] for c in CORE_FINDINGS[name]
                                                    if c in CORE_FINDINGS_WHY)


@pytest.mark.parametrize("name", sorted(CORE_FINDINGS))
def test_known_core_findings_still_fail(name, request):
    case = next(c for c in CASES if c.name == name)
    result = result_of(case)
    request.applymarker(pytest.mark.xfail(strict=True, reason=_why(name)))
    assert result.passed, "\n".join(result.failures)
