"""``legsim cache`` and ``legsim cache clear`` (legsim/commands/cache.py,
legsim/compiled/cache.py): clearing removes numba's cache files of every legsim version and the
folders they leave empty, and nothing else of a folder ``LEGSIM_CACHE_DIR`` points at."""

from __future__ import annotations

from legsim.cli import main
from legsim.version import __version__


def _cache_tree(root):
    """A cache root as legsim leaves it (this version's and an older version's entries, in a
    subfolder too), with a user's own files beside them."""
    for version in (__version__, "0.0.9"):
        (root / version / "relaxed").mkdir(parents=True)
        (root / version / "loop.run-77.py311.nbi").write_bytes(b"index")
        (root / version / "loop.run-77.py311.1.nbc").write_bytes(b"code")
        (root / version / "relaxed" / "rules.step-12.py311.nbi").write_bytes(b"index")
    (root / "notes.txt").write_text("mine")
    (root / "data").mkdir()
    (root / "data" / "results.csv").write_text("1,2\n")
    (root / __version__ / "keep.me").write_text("also mine")


def test_clear_removes_compiled_code_and_keeps_everything_else(tmp_path, monkeypatch, capsys):
    root = tmp_path / "cache"
    _cache_tree(root)
    monkeypatch.setenv("LEGSIM_CACHE_DIR", str(root))
    assert main(["cache", "clear"]) == 0
    out = capsys.readouterr().out
    assert f"removed 6 files of compiled code from {root}" in out
    assert "kept 3 files that are not compiled code" in out
    left = sorted(str(p.relative_to(root)) for p in root.rglob("*"))
    assert left == sorted([__version__, f"{__version__}/keep.me", "data", "data/results.csv", "notes.txt"])
    assert (root / "notes.txt").read_text() == "mine"
    assert not (root / "0.0.9").exists()  # emptied of compiled code, so removed


def test_show_counts_what_clear_removes(tmp_path, monkeypatch, capsys):
    """The files shown as compiled code are the ones clear removes: every version's numba files,
    not a user's file in this version's folder."""
    root = tmp_path / "cache"
    _cache_tree(root)
    monkeypatch.setenv("LEGSIM_CACHE_DIR", str(root))
    assert main(["cache"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{root}: 6 files, 0.0 MB of compiled code, every version's")
    assert "3 other files there are not compiled code and are kept" in out
    assert main(["cache", "clear"]) == 0
    assert "removed 6 files" in capsys.readouterr().out
    assert main(["cache"]) == 0
    assert capsys.readouterr().out.startswith(f"{root}: 0 files")


def test_clear_of_a_missing_folder_removes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("LEGSIM_CACHE_DIR", str(tmp_path / "none"))
    assert main(["cache", "clear"]) == 0
    assert "removed 0 files" in capsys.readouterr().out
    assert not (tmp_path / "none").exists()
