"""Package layout: the repository's top-level folders are installed under the ``legsim`` name.

``robots/``, ``viz/`` and ``scenarios/`` stay where a reader of the repository expects them,
but install as ``legsim.robots``, ``legsim.viz`` and ``legsim.scenarios`` so that no generic
top-level name reaches site-packages (a user's own ``robots/`` folder shadows nothing). The
rest of the configuration is in pyproject.toml.
"""

from setuptools import find_packages, setup

FOLDERS = {"legsim": "legsim", "legsim.robots": "robots", "legsim.viz": "viz", "legsim.scenarios": "scenarios"}


def packages() -> list[str]:
    found = []
    for package, folder in FOLDERS.items():
        found.append(package)
        found += [f"{package}.{sub}" for sub in find_packages(folder)]
    return found


setup(packages=packages(), package_dir=FOLDERS)
