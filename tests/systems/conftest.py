"""Fixtures of the system tests: the exact references of Table I's two examples (built once per
module: their impact searches are the expensive part)."""

import pytest

from legsim.systems.oscillator import OscillatorReference


@pytest.fixture(scope="module")
def ref1() -> OscillatorReference:
    return OscillatorReference.example("ex1")


@pytest.fixture(scope="module")
def ref2() -> OscillatorReference:
    return OscillatorReference.example("ex2")
