"""Package layout: the repository's top-level folders are installed under the ``legsim`` name.

``robots/``, ``viz/`` and ``scenarios/`` stay where a reader of the repository expects them,
but install as ``legsim.robots``, ``legsim.viz`` and ``legsim.scenarios`` so that no generic
top-level name reaches site-packages (a user's own ``robots/`` folder shadows nothing). The
rest of the configuration is in pyproject.toml.

One optional C++ extension, ``legsim.robots._native._pinlegsim``: Pinocchio's algorithms behind a
plain C ABI for the robots' model functions (robots/_native/). It is built from the Pinocchio and
Eigen headers of the build environment (the ``libpinocchio`` and ``cmeel-eigen`` wheels named in
pyproject.toml's build requirements); without a C++ compiler or those headers the build skips it
and legsim's robots cannot be built (``legsim.robots._native.status()`` says why);
``LEGSIM_BUILD_NATIVE=0`` skips it on purpose.
"""

import os
import sys
from pathlib import Path

from setuptools import Extension, find_packages, setup

FOLDERS = {"legsim": "legsim", "legsim.robots": "robots", "legsim.viz": "viz", "legsim.scenarios": "scenarios"}


def packages() -> list[str]:
    found = []
    for package, folder in FOLDERS.items():
        found.append(package)
        found += [f"{package}.{sub}" for sub in find_packages(folder)]
    return found


def cmeel_include() -> Path | None:
    """The include folder of the cmeel prefix holding both Pinocchio's and Eigen's headers."""
    for entry in sys.path:
        include = Path(entry) / "cmeel.prefix" / "include"
        if (include / "pinocchio" / "multibody.hpp").exists() and (include / "eigen3" / "Eigen" / "Core").exists():
            return include
    return None


def native_extensions() -> list[Extension]:
    if os.environ.get("LEGSIM_BUILD_NATIVE", "1") == "0":
        print("legsim: LEGSIM_BUILD_NATIVE=0: building without the native library", file=sys.stderr)
        return []
    include = cmeel_include()
    if include is None:
        print("legsim: Pinocchio or Eigen headers not found: building without the native library", file=sys.stderr)
        return []
    # Pinocchio's own compile definitions (from its CMake config), header-only use.
    defines = [
        ("NDEBUG", None),
        ("BOOST_MPL_LIMIT_LIST_SIZE", "30"),
        ("BOOST_MPL_LIMIT_VECTOR_SIZE", "30"),
        ("BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", None),
        ("BOOST_FUSION_INVOKE_MAX_ARITY", "12"),
    ]
    return [
        Extension(
            "legsim.robots._native._pinlegsim",
            ["robots/_native/pinlegsim.cpp"],
            depends=["robots/_native/planar_tree.hpp", "robots/_native/small_cholesky.hpp"],
            language="c++",
            include_dirs=[str(include), str(include / "eigen3")],
            define_macros=defines,
            # -O3 inlines Pinocchio's small spatial-algebra functions (about 30% off a field evaluation);
            # hidden visibility: only the C interface is exported (pinlegsim.cpp), and Pinocchio's
            # functions are called directly inside the library (a little faster, same arithmetic).
            extra_compile_args=["-std=c++17", "-O3", "-g0", "-w", "-fvisibility=hidden", "-fvisibility-inlines-hidden"],
            optional=True,
        )
    ]


setup(packages=packages(), package_dir=FOLDERS, ext_modules=native_extensions())
