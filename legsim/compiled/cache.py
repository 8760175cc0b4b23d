"""Where legsim's compiled code is kept, and when it is stale.

numba caches a function's machine code beside its source and trusts it while that one file is
unchanged; a function that calls compiled functions of other files (the step loop calls the
rules, a robot's model functions call the native library's helpers) would load stale code after
those change. legsim's own functions are therefore cached by a locator of their own, installed
in front of numba's: in ``cache_dir()`` (per legsim version, in the user's cache folder), with a
stamp that is the digest of the function's file and of every legsim module it imports, directly
or not. A user's model functions (outside the package) keep numba's own caching.

``LEGSIM_CACHE_DIR`` overrides the folder (the tests put it in a temporary folder).

**Prebuilt code.** A first run compiles the step loop and the bundled models' functions for
about a minute. So an install compiles them ahead of time (``legsim.prebuild``, run by
``make install`` and by a wheel's build) for the generic x86-64 processor, into the package's own
folder ``_prebuilt/<version>`` (``PREBUILT_DIR``). Such code runs on any x86-64 processor; numba
would not load it on another (its cache entries name the processor they were compiled for), so
legsim's functions get a cache (``LegsimCache``) that looks in the user's cache first, then among
the prebuilt entries under the generic processor's name. Code compiled at run time is for this
machine's processor and stays in the user's cache only. Entries are found by the module's path
inside the package, not by where the package is installed.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Iterable
from functools import cache
from pathlib import Path
from typing import Any

from numba.core import caching

from ..version import __version__

#: The installed package's root: legsim/, whose parent holds its siblings (robots/, viz/ are
#: installed inside it; in a source checkout they sit beside it).
PACKAGE_ROOT = Path(__file__).resolve().parent.parent
_ROOTS = (PACKAGE_ROOT, PACKAGE_ROOT.parent / "robots", PACKAGE_ROOT.parent / "viz")


def cache_dir() -> Path:
    """The folder of legsim's compiled code: ``$LEGSIM_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/legsim/kernels/<version>`` (``~/.cache/legsim/kernels/<version>``)."""
    env = os.environ.get("LEGSIM_CACHE_DIR")
    if env:
        return Path(env) / __version__
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "legsim" / "kernels" / __version__


#: The files numba's caches consist of: an index per function and one data file per compiled
#: signature. ``clear`` removes these and nothing else.
CACHE_SUFFIXES = (".nbi", ".nbc")


def clear() -> tuple[Path, int, list[Path]]:
    """Remove legsim's compiled code, every version's: numba's cache files (``CACHE_SUFFIXES``)
    under the cache's root (``cache_dir().parent``, the folder ``LEGSIM_CACHE_DIR`` names), then
    the folders that leaves empty. Anything else there, a user's own files in a folder
    ``LEGSIM_CACHE_DIR`` points at, is kept. Returns (the root, the files removed, the other
    files found and kept)."""
    root, compiled, kept = cache_files()
    for entry in compiled:
        entry.unlink()
    if root.is_dir():
        _remove_empty_folders(root)
    return root, len(compiled), kept


def cache_files() -> tuple[Path, list[Path], list[Path]]:
    """(the cache's root, its files of compiled code of every version, its other files): what
    ``clear`` removes and what it keeps."""
    root = cache_dir().parent
    if not root.is_dir():
        return root, [], []
    compiled, other = [], []
    for entry in sorted(root.rglob("*")):
        if entry.is_file() and not entry.is_symlink() and entry.suffix in CACHE_SUFFIXES:
            compiled.append(entry)
        elif entry.is_symlink() or entry.is_file():
            other.append(entry)
    return root, compiled, other


def _remove_empty_folders(root: Path) -> None:
    """Remove the empty folders under ``root`` (not ``root`` itself), deepest first, so that a
    folder holding only empty folders goes too."""
    folders = [d for d in root.rglob("*") if d.is_dir() and not d.is_symlink()]
    for folder in sorted(folders, key=lambda d: -len(d.parts)):
        if not any(folder.iterdir()):
            folder.rmdir()


#: The package's own folder of prebuilt code, portable across x86-64 processors.
PREBUILT_DIR = PACKAGE_ROOT / "_prebuilt" / __version__
#: The processor prebuilt code is compiled for (numba's ``NUMBA_CPU_NAME``).
PREBUILT_CPU = "generic"


def _owned(path: Path) -> bool:
    return any(root in path.parents for root in _ROOTS)


@cache
def package_subpath(py_file: str | Path) -> str:
    """The folder of a legsim source file inside the package (``relaxed``, ``robots/bridge``),
    the same in a source checkout and in an installed package."""
    path = Path(py_file).resolve()
    folder = path.parent
    for root in (PACKAGE_ROOT, PACKAGE_ROOT.parent):
        if root == folder or root in folder.parents:
            relative = folder.relative_to(root).as_posix()
            return relative or "."
    return folder.name


#: ``from <dots><module> import <names>``; names either in parentheses (over several lines) or
#: up to the end of the line, a comment or a semicolon.
_FROM_IMPORT = re.compile(r"(?:^|;)[ \t]*from[ \t]+(\.*)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#;]*)", re.MULTILINE)
#: ``import <module> [as <name>][, ...]``.
_PLAIN_IMPORT = re.compile(r"(?:^|;)[ \t]*import[ \t]+([^\n#;]+)", re.MULTILINE)
#: Triple-quoted strings: docstrings show imports in examples.
_LONG_STRING = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'')

#: One import of a source file: (dots of a relative import, module or None, the name imported
#: from it or None for a plain ``import <module>``).
ImportStatement = tuple[int, str | None, str | None]


def import_statements(source: str) -> set[ImportStatement]:
    """The imports written in ``source``, at any depth (inside functions and ``if`` blocks too).

    A scan of the text, not Python's parser: parsing every module a run's compiled code depends
    on took about half a second of each first run. It reads the forms ruff's formatting writes
    (no backslash continuations); ``tests/packaging/test_compiled_stamps.py`` checks it finds what
    Python's parser finds in every file of the package."""
    found: set[ImportStatement] = set()
    source = _LONG_STRING.sub("", source)
    for dots, module, names in _FROM_IMPORT.findall(source):
        lines = (line.split("#")[0] for line in names.strip().strip("()").splitlines())
        for alias in " ".join(lines).split(","):
            if alias.split():
                found.add((len(dots), module or None, alias.split()[0]))
    for names in _PLAIN_IMPORT.findall(source):
        found.update((0, alias.split()[0], None) for alias in names.split(",") if alias.split())
    return found


@cache
def _imports(path: Path) -> tuple[Path, ...]:
    """The legsim source files ``path`` imports (relative imports and ``legsim.*``)."""
    try:
        source = path.read_text()
    except OSError:
        return ()
    found: list[Path | None] = []
    for level, module, name in sorted(import_statements(source), key=str):
        if name is None:
            if module is not None and module.startswith("legsim."):
                found.append(_module_file(_package_path(module.split(".")[1:])))
            continue
        base = _resolve(path, module, level)
        if base is not None:
            found += [_module_file(base), _module_file(base / name) if name != "*" else None]
    return tuple(dict.fromkeys(p for p in found if p is not None))


def _resolve(path: Path, module: str | None, level: int) -> Path | None:
    if level == 0:
        if module is None or not module.startswith("legsim"):
            return None
        return _package_path(module.split(".")[1:])
    base = path.parent
    for _ in range(level - 1):
        base = base.parent
    return base.joinpath(*module.split(".")) if module else base


def _package_path(parts: list[str]) -> Path:
    """The path of ``legsim.<parts>``: inside the package, or for ``robots`` and ``viz`` in a
    source checkout, their folders beside it (setup.py installs them as legsim.robots, legsim.viz)."""
    inside = PACKAGE_ROOT.joinpath(*parts)
    if parts and parts[0] in ("robots", "viz") and not (PACKAGE_ROOT / parts[0]).exists():
        return PACKAGE_ROOT.parent.joinpath(*parts)
    return inside


@cache
def _module_file(base: Path) -> Path | None:
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate.resolve()
    return None


@cache
def source_digest(path: Path) -> str:
    """The digest of ``path`` and of every legsim module it imports, directly or not."""
    seen: dict[Path, None] = {}
    todo = [path.resolve()]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen[current] = None
        todo.extend(_imports(current))
    digest = hashlib.sha256()
    # Ordered by the path inside the package, the same whether robots/ sits beside legsim/ (a
    # checkout) or inside it (an install): prebuilt entries are found in both.
    for entry in sorted(seen, key=lambda found: (package_subpath(found), found.name)):
        digest.update(str(entry.name).encode())
        digest.update(entry.read_bytes())
    return digest.hexdigest()[:24]


#: Files whose code shapes the machine code of other files' functions, by the latter: the
#: kernel's module (its calls into the function table, what it inlines) for the loop's modules,
#: whose functions are compiled only through it. Their digests join those functions' stamps.
_COMPILED_UNDER: dict[Path, tuple[Path, ...]] = {}


def compiled_under(sources: Iterable[str | Path], compilers: Iterable[str | Path]) -> None:
    """Declare that the functions of the files ``sources`` are compiled under the code of the
    files ``compilers``: a change of either makes their cached code stale."""
    under = tuple(Path(c).resolve() for c in compilers)
    for source in sources:
        _COMPILED_UNDER[Path(source).resolve()] = under


def stamp(path: Path) -> str:
    """The stamp of the compiled functions of ``path``: its ``source_digest``, with those of the
    files it is compiled under (``compiled_under``)."""
    digest = source_digest(path)
    under = _COMPILED_UNDER.get(path.resolve(), ())
    if not under:
        return digest
    joined = digest + "".join(source_digest(c) for c in under)
    return hashlib.sha256(joined.encode()).hexdigest()[:24]


class LegsimCacheLocator(caching._CacheLocator):
    """numba's cache locator for legsim's own functions (module docstring)."""

    #: The folder holding the entries (the user's cache; the prebuilt one in ``PrebuiltLocator``).
    root: Path | None = None

    def __init__(self, py_func: Any, py_file: str) -> None:
        self._py_file = Path(py_file).resolve()
        self._lineno = py_func.__code__.co_firstlineno
        base = cache_dir() if self.root is None else self.root
        self._cache_path = str(base / package_subpath(py_file))

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> str:
        return stamp(self._py_file)

    def get_disambiguator(self) -> str:
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> LegsimCacheLocator | None:
        if not py_file or not os.path.exists(py_file) or not _owned(Path(py_file).resolve()):
            return None
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:
            return None
        return self


class PrebuiltLocator(LegsimCacheLocator):
    """The locator of the package's prebuilt entries (read only)."""

    root = PREBUILT_DIR

    def ensure_cache_path(self) -> None:
        if not os.path.isdir(self._cache_path):
            raise OSError(f"no prebuilt code in {self._cache_path}")


class _PrebuiltImpl(caching.CompileResultCacheImpl):
    _locator_classes = [PrebuiltLocator]  # noqa: RUF012 -- numba reads this class attribute


class PrebuiltCache(caching.FunctionCache):
    """The prebuilt entries of a function, found under the generic processor's name."""

    _impl_class = _PrebuiltImpl

    def _index_key(self, sig: Any, codegen: Any) -> Any:
        key = super()._index_key(sig, codegen)
        return (key[0], (key[1][0], PREBUILT_CPU, ""), key[2])

    def save_overload(self, sig: Any, data: Any) -> None:
        """Prebuilt entries are written by the prebuild only (as the user cache's, under
        ``NUMBA_CPU_NAME=generic``), never at run time."""


class LegsimCache(caching.FunctionCache):
    """The cache of legsim's own compiled functions: the user's, then the prebuilt entries."""

    def __init__(self, py_func: Any) -> None:
        super().__init__(py_func)
        try:
            self._prebuilt: PrebuiltCache | None = PrebuiltCache(py_func)
        except RuntimeError:  # no prebuilt folder for this function (not prebuilt, or a new module)
            self._prebuilt = None

    def load_overload(self, sig: Any, target_context: Any) -> Any:
        found = super().load_overload(sig, target_context)
        if found is None and self._prebuilt is not None:
            found = self._prebuilt.load_overload(sig, target_context)
        return found


def use_legsim_cache(dispatcher: Any) -> Any:
    """Give a dispatcher of legsim's own code the cache with prebuilt entries; returns it."""
    py_file = getattr(getattr(dispatcher, "py_func", None), "__code__", None)
    if py_file is not None and _owned(Path(py_file.co_filename).resolve()):
        dispatcher._cache = LegsimCache(dispatcher.py_func)
    return dispatcher


def install() -> None:
    """Put legsim's locator in front of numba's (once)."""
    locators = caching.CacheImpl._locator_classes
    if LegsimCacheLocator not in locators:
        locators.insert(0, LegsimCacheLocator)
