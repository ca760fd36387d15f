"""The kernel cache's stamp: a change to any kernel file drops every cached kernel."""

from pathlib import Path

from drake_uuv.kernel_cache import STAMP, kernel_digest, refresh_kernel_cache


def _package(root: Path) -> tuple[Path, Path, Path]:
    (root / "models" / "__pycache__").mkdir(parents=True)
    callee = root / "models" / "callee.py"
    callee.write_text("from numba import njit\n")
    (root / "plain.py").write_text("x = 1\n")
    cached = root / "models" / "__pycache__" / "caller.f-3.py311.1.nbc"
    index = root / "models" / "__pycache__" / "caller.f-3.py311.nbi"
    return callee, cached, index


def _cache(*paths: Path) -> None:
    for path in paths:
        path.write_bytes(b"compiled")


def test_an_edited_callee_drops_every_cached_kernel_once(tmp_path: Path) -> None:
    callee, cached, index = _package(tmp_path)
    _cache(cached, index)
    assert refresh_kernel_cache(tmp_path)  # no stamp yet: the cache predates it
    assert not cached.exists() and not index.exists()
    assert (tmp_path / "__pycache__" / STAMP).read_text() == kernel_digest(tmp_path)

    _cache(cached, index)
    assert not refresh_kernel_cache(tmp_path)  # nothing changed: the cache stays
    assert cached.exists() and index.exists()

    callee.write_text("from numba import njit\nTEMPERING_FLOOR = 20\n")
    assert refresh_kernel_cache(tmp_path)
    assert not cached.exists() and not index.exists()


def test_a_file_without_kernels_leaves_the_cache(tmp_path: Path) -> None:
    _, cached, index = _package(tmp_path)
    refresh_kernel_cache(tmp_path)
    _cache(cached, index)
    (tmp_path / "plain.py").write_text("x = 2\n")
    assert not refresh_kernel_cache(tmp_path)
    assert cached.exists()


def test_the_digest_names_the_file_as_well_as_its_bytes(tmp_path: Path) -> None:
    callee, _, _ = _package(tmp_path)
    before = kernel_digest(tmp_path)
    callee.rename(callee.with_name("renamed.py"))
    assert kernel_digest(tmp_path) != before
