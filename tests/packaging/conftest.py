"""The packaging tests' build environment, made once per test process."""

import pytest

from helpers.packaging import build_environment


@pytest.fixture(scope="session")
def build_python(tmp_path_factory):
    """The interpreter of a fresh environment holding the build requirements the tests need."""
    return build_environment(tmp_path_factory.mktemp("build-env") / "venv")
