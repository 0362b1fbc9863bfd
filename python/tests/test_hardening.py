"""Audit 2, U15 (issue 36): the package namespace holds the API only, ``progress`` takes a
bool, None or a callable, and ``FitResult.save`` refuses a symbolic link as the command
line does. Each test fails on the code the audit ran."""

import json

import pytest

import brdf_basis as bb


def test_namespace_holds_no_helper_imports():
    for name in ["np", "Any", "Callable", "Optional", "Sequence", "Union", "dataclass", "field", "annotations"]:
        assert not hasattr(bb, name), name
    assert all(hasattr(bb, name) for name in bb.__all__)


def test_progress_is_a_bool_none_or_a_callable():
    c = bb.Collection.default()
    for bad in [5, "yes", 0.5]:
        with pytest.raises(TypeError, match=r"progress: expected True, False, None or a callable"):
            bb.distance_matrix(c, stride=8, backend="cpu", progress=bad)
    for ok in [True, False, None]:
        assert bb.distance_matrix(c, stride=8, backend="cpu", progress=ok).shape[0] == len(c.names)


def test_fit_result_save_refuses_a_symbolic_link(tmp_path):
    c = bb.Collection.default()
    r = bb.fit(c, ["polished-gold"], ["polished-copper"], stride=8, backend="cpu")
    owned = tmp_path / "owned.txt"
    owned.write_text("mine")
    link = tmp_path / "f.json"
    link.symlink_to(owned)
    with pytest.raises(ValueError, match="symbolic link"):
        r.save(link)
    assert owned.read_text() == "mine" and link.is_symlink()
    (tmp_path / "d").mkdir()
    with pytest.raises(ValueError, match="not a regular file"):
        r.save(tmp_path / "d")
    r.save(tmp_path / "g.json")
    r.save(tmp_path / "g.json")  # replaced
    assert json.loads((tmp_path / "g.json").read_text()) == json.loads(r.to_json())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "f.json", "g.json", "owned.txt"]
