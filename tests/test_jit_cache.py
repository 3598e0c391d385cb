"""numba's cache is dropped exactly when a source the compiled code depends on changes."""

from __future__ import annotations

from pathlib import Path

import pytest

from drillstring.model.kernel.jit import drop_stale_cache, sources_digest


def _tree(tmp_path: Path) -> tuple[list[Path], Path, Path]:
    src = tmp_path / "pkg"
    (src / "__pycache__").mkdir(parents=True)
    compiled = src / "kernel.py"
    helper = src / "helper.py"
    compiled.write_text("x = 1\n")
    helper.write_text("y = 2\n")
    return [compiled, helper], compiled, src / "__pycache__" / "stamp.sha256"


def _entries(compiled: Path, *names: str) -> list[Path]:
    out = []
    for name in names:
        entry = compiled.parent / "__pycache__" / f"{compiled.stem}.{name}"
        entry.write_bytes(b"compiled")
        out.append(entry)
    return out


def test_cache_is_dropped_once_then_kept_until_a_source_changes(tmp_path: Path) -> None:
    sources, compiled, stamp = _tree(tmp_path)
    stale = _entries(compiled, "f-1.py311.nbi", "f-1.py311.1.nbc")
    other = compiled.parent / "__pycache__" / "helper.f-1.py311.nbi"
    other.write_bytes(b"not ours")

    assert drop_stale_cache(sources, [compiled], stamp) is True
    assert not any(p.exists() for p in stale) and other.exists()
    assert stamp.read_text().strip() == sources_digest(sources)

    fresh = _entries(compiled, "f-2.py311.nbi")
    assert drop_stale_cache(sources, [compiled], stamp) is False
    assert fresh[0].exists()

    sources[1].write_text("y = 3\n")  # a dependency, not the compiled module itself
    assert drop_stale_cache(sources, [compiled], stamp) is True
    assert not fresh[0].exists()


def test_digest_depends_on_names_contents_and_order(tmp_path: Path) -> None:
    sources, _, _ = _tree(tmp_path)
    d = sources_digest(sources)
    assert sources_digest(list(reversed(sources))) != d
    sources[0].write_text("x = 1 \n")
    assert sources_digest(sources) != d


def test_read_only_cache_is_left_alone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sources, compiled, stamp = _tree(tmp_path)
    (entry,) = _entries(compiled, "f-1.py311.nbi")

    def refuse(self: Path, missing_ok: bool = False) -> None:
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "unlink", refuse)
    assert drop_stale_cache(sources, [compiled], stamp) is False
    assert entry.exists() and not stamp.exists()


def test_unreadable_source_is_an_error_naming_it(tmp_path: Path) -> None:
    sources, compiled, stamp = _tree(tmp_path)
    missing = tmp_path / "pkg" / "gone.py"
    with pytest.raises(FileNotFoundError, match="gone.py"):
        drop_stale_cache([*sources, missing], [compiled], stamp)
