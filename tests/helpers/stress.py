"""Shared pieces of the stress tests: the core findings a stress case may be failing on.

``CORE_FINDINGS`` names, per case, the checks that fail because of a known core bug the stress
suite found (docs/stress.md, "Findings"), and ``CORE_FINDINGS_WHY`` the bug, per case or per
check. A listed case must fail exactly those checks and nothing else: test_cases_quick.py then
strict-xfails it, so the day the core is fixed the test passes unexpectedly and the entry has
to go. Empty while no case exposes a known core bug; tests/stress/test_core_findings.py keeps
the reproductions of the bugs the suite has found.
"""

CORE_FINDINGS: dict[str, set[str]] = {}
CORE_FINDINGS_WHY: dict[str, str] = {}


def known_failures(case_name: str) -> set[str]:
    """The checks of a case that fail because of a known core finding (empty for most)."""
    return CORE_FINDINGS.get(case_name, set())


def finding_reason(case_name: str) -> str:
    """Why a listed case fails: its own entry in CORE_FINDINGS_WHY, else those of its checks."""
    return CORE_FINDINGS_WHY.get(case_name) or "; ".join(
        CORE_FINDINGS_WHY[check] for check in CORE_FINDINGS[case_name] if check in CORE_FINDINGS_WHY
    )
