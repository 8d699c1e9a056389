"""Library meshes: every procedural instance builds; a sample exports to files that fit its
category's size range; named meshes whose source is missing or broken fail naming the file."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conceptfusion.errors import SimError
from sim_envs.assets.library import catalogue, export_instance, get_instance
from sim_envs.assets.library.export import instance_parts
from sim_envs.assets.library.geometry import merge
from sim_envs.assets.library.shapes import SHAPES, build_shape
from sim_envs.assets.library.textures import texture_image


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CF_ASSET_CACHE", str(tmp_path_factory.mktemp("assets")))
        yield


def _sample(step: int = 23):
    """A deterministic sample: every ``step``-th instance, plus every named mesh kind once."""
    items = list(catalogue().instances.values())
    named = {i.mesh.mesh: i for i in items if i.mesh is not None}
    return sorted({*items[::step], *named.values()}, key=lambda i: i.id)


def test_every_procedural_instance_builds_a_non_empty_finite_mesh():
    for inst in catalogue().instances.values():
        if inst.mesh is not None:
            continue
        m = merge([p.mesh for p in instance_parts(inst)])
        assert len(m.faces) >= 12 and np.isfinite(m.vertices).all(), inst.id
        assert m.uv.shape == (len(m.vertices), 2) and m.uv.min() >= -1e-9 and m.uv.max() <= 1 + 1e-9, inst.id
        assert (np.ptp(m.vertices, axis=0) > 0).all(), inst.id


def test_every_shape_variant_is_used():
    used = {i.variant for i in catalogue().instances.values()}
    assert set(SHAPES) <= used


@pytest.mark.parametrize("inst", _sample(), ids=lambda i: i.id)
def test_exported_instance_fits_its_size_range(inst):
    exp = export_instance(inst)
    lo, hi = catalogue().categories[inst.category].size_range
    assert lo * 0.999 <= max(exp.size) <= hi * 1.001
    assert max(exp.size) == pytest.approx(inst.scale, rel=1e-3)
    lines = exp.visual.read_text().splitlines()
    v = np.array([[float(x) for x in ln.split()[1:4]] for ln in lines if ln.startswith("v ")])
    assert np.allclose(v.min(0), [-0.5, -0.5, 0.0], atol=1e-4) and np.allclose(v.max(0), [0.5, 0.5, 1.0], atol=1e-4)
    assert sum(ln.startswith("vt ") for ln in lines) == len(v)
    assert exp.hulls and all(h.stat().st_size > 0 for h in exp.hulls)
    assert exp.texture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert export_instance(inst.id) == exp  # second call: the cache entry


def test_open_vessels_collide_as_floor_and_wall_pieces():
    exp = export_instance("bowl-000")
    assert len(exp.hulls) >= 9  # floor + 8 wall sectors
    assert len(export_instance("book-000").hulls) >= 1


def test_a_broken_cache_entry_is_rebuilt():
    exp = export_instance("cup-001")
    exp.hulls[0].unlink()
    again = export_instance("cup-001")
    assert again.hulls[0].is_file()


def test_textures_are_deterministic_and_coloured():
    a, b = texture_image("wood", "brown", 32), texture_image("wood", "brown", 32)
    assert a.shape == (32, 32, 3) and a.dtype == np.uint8 and np.array_equal(a, b)
    red = texture_image("plastic", "red", 32).reshape(-1, 3).mean(0)
    assert red[0] > 2 * red[1] and red[0] > 2 * red[2]
    with pytest.raises(SimError, match="unknown material 'wod'; did you mean 'wood'"):
        texture_image("wod", "red")


def test_a_named_mesh_missing_or_broken_names_the_file_and_field(tmp_path):
    duck = get_instance("pb-duck")
    missing = dataclasses.replace(duck, id="pb-gone", mesh=dataclasses.replace(duck.mesh, mesh=str(tmp_path / "gone.obj")))
    with pytest.raises(SimError, match=r"gone\.obj: asset file missing \(instance 'pb-gone'\.mesh\)"):
        export_instance(missing)
    (tmp_path / "junk.obj").write_text("this is not a mesh\n")
    broken = dataclasses.replace(duck, id="pb-junk", mesh=dataclasses.replace(duck.mesh, mesh=str(tmp_path / "junk.obj")))
    with pytest.raises(SimError, match=r"junk\.obj: asset file broken.*\(instance 'pb-junk'\.mesh\)"):
        export_instance(broken)


def test_unknown_shape_variant_names_the_nearest():
    with pytest.raises(KeyError, match="unknown shape variant 'mug_rond'; did you mean 'mug_round'"):
        build_shape("mug_rond", {})
