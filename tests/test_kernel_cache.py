"""numba's cached kernels are dropped when any numba source of the package changes."""

from pathlib import Path

import prehensile
from prehensile import kernel_cache


def _package(root: Path) -> dict[str, Path]:
    """A package with two numba modules (one in a subpackage), a plain one and cached kernels."""
    (root / "sub").mkdir(parents=True)
    files = {"kernels": root / "kernels.py", "inner": root / "sub" / "inner.py", "plain": root / "plain.py"}
    files["kernels"].write_text("from numba import njit\n")
    files["inner"].write_text("import numba\n")
    files["plain"].write_text("x = 1\n")
    return files


def _cache(folder: Path) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / "kernels.f-1.py311.nbi", folder / "kernels.f-1.py311.1.nbc"]
    for path in paths:
        path.write_bytes(b"compiled")
    return paths


def test_cached_kernels_survive_until_a_numba_source_changes(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    root = tmp_path / "pkg"
    files = _package(root)
    pyc = root / "__pycache__" / "plain.cpython-311.pyc"
    old = _cache(root / "__pycache__") + _cache(root / "sub" / "__pycache__")
    pyc.write_bytes(b"bytecode")
    assert kernel_cache.refresh(root) == 4  # no record of the sources they came from
    assert not any(path.exists() for path in old) and pyc.exists()
    current = _cache(root / "sub" / "__pycache__")
    assert kernel_cache.refresh(root) == 0
    files["plain"].write_text("x = 2\n")  # not a numba module
    assert kernel_cache.refresh(root) == 0 and all(path.exists() for path in current)
    files["kernels"].write_text("from numba import njit  # edited\n")  # inlined into inner's kernels
    assert kernel_cache.refresh(root) == 2
    assert not any(path.exists() for path in current) and pyc.exists()


def test_cached_kernels_count_index_files_and_the_cli_says_when_it_compiles(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from prehensile.cli.main import app

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    root = tmp_path / "pkg"
    _package(root)
    assert kernel_cache.cached_kernels(root) == 0
    _cache(kernel_cache.cache_folders(root)[1])
    assert kernel_cache.cached_kernels(root) == 1  # an index file per kernel, beside its compiled code
    note = "First run: numba compiles the kernels"
    for cached, command, shown in ((0, ["fk", "nowhere"], True), (0, ["robot", "list"], False),
                                   (1, ["fk", "nowhere"], False)):
        monkeypatch.setattr(kernel_cache, "cached_kernels", lambda count=cached: count)
        assert (note in CliRunner().invoke(app, command).output) == shown, (cached, command)


def test_caches_under_numba_cache_dir_are_found(tmp_path, monkeypatch):
    root = tmp_path / "pkg"
    files = _package(root)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    folders = kernel_cache.cache_folders(root)
    assert all(folder.parent == tmp_path / "cache" for folder in folders) and len(folders) == 2
    kernel_cache.refresh(root)
    cached = _cache(folders[1])
    files["inner"].write_text("import numba  # edited\n")
    assert kernel_cache.refresh(root) == 2 and not any(path.exists() for path in cached)


def test_importing_prehensile_records_its_kernel_sources():
    root = Path(prehensile.__file__).resolve().parent
    marker = kernel_cache.cache_folders(root)[0] / kernel_cache.MARKER
    assert marker.read_text() == kernel_cache.sources_digest(root)
