"""Folders of results are replaced whole: the old one or the new one, never a mixture; JSON is
written as JSON (no bare NaN)."""

from __future__ import annotations

import math
from pathlib import Path

import fmu_testlib as tl
import numpy as np
import pytest

from drillstring.fileio import replace_dir, write_json


def _folder(path: Path, **files: str) -> Path:
    path.mkdir()
    for name, text in files.items():
        (path / name).write_text(text)
    return path


def test_new_folder_takes_the_place_of_the_old_one(tmp_path: Path) -> None:
    old = _folder(tmp_path / "map", results="old", stale="only in the old run")
    new = _folder(tmp_path / ".map.new", results="new")
    assert replace_dir(new, old) == old
    assert sorted(p.name for p in old.iterdir()) == ["results"]
    assert (old / "results").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map"]


def test_first_run_has_no_old_folder(tmp_path: Path) -> None:
    new = _folder(tmp_path / ".map.new", results="new")
    replace_dir(new, tmp_path / "map")
    assert (tmp_path / "map" / "results").read_text() == "new"


def test_failed_replacement_keeps_the_old_folder(tmp_path: Path) -> None:
    old = _folder(tmp_path / "map", results="old")
    with pytest.raises(FileNotFoundError):
        replace_dir(tmp_path / "missing", old)
    assert (old / "results").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map"]


def test_json_without_a_value_is_null(tmp_path: Path) -> None:
    obj = {"a": math.nan, "b": [1.5, math.inf, (-math.inf, np.float64("nan"))], "c": {"d": 2.0}}
    path = write_json(tmp_path / "summary.json", obj)
    assert tl.strict_json(path.read_text()) == {
        "a": None,
        "b": [1.5, None, [None, None]],
        "c": {"d": 2.0},
    }
