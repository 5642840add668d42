"""Materials: the apparent-reflectivity formula, Envisat's defaults, per-part settings in the
scenario, colours read from mesh files, and the intensity column they produce."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import scenario

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scene.materials import (
    MATERIAL_LIBRARY,
    Material,
    MaterialTable,
    material_from_colour,
    specular_peak,
)

PLATE = {"model": "plate", "options": {"size_m": [20, 20]}}


def _tilted(angle_deg: float) -> dict:
    """A plate 10 m ahead turned by ``angle_deg`` about the vertical."""
    return {"position_m": [10, 0, 0], "euler_deg": [0, 0, angle_deg]}


def _with_materials(sc, materials: dict):
    """``sc`` with its first target's ``materials`` set."""
    from lidarsim_core.scenario import scenario_from_dict

    data = sc.model_dump()
    data["targets"][0]["materials"] = materials
    return scenario_from_dict(data)


# ---- the formula -----------------------------------------------------------------------------
def test_lambertian_gives_rho_cos_theta():
    theta = np.radians([0, 10, 30, 60, 85, 90])
    rho = Material(diffuse_reflectivity=0.3).effective_reflectivity(np.cos(theta))
    np.testing.assert_allclose(rho, 0.3 * np.cos(theta), atol=1e-15)


def test_specular_lobe_is_the_beckmann_monostatic_return():
    mat = Material(diffuse_reflectivity=0.1, specular_reflectance=0.04, specular_slope_deg=1.0)
    m = math.tan(math.radians(1.0))
    for deg in (0.0, 0.5, 1.0, 2.0, 20.0):
        t = math.radians(deg)
        expected = (0.1 * math.cos(t)
                    + 0.04 * math.exp(-math.tan(t) ** 2 / m ** 2) / (4 * m * m * math.cos(t) ** 5))
        assert mat.effective_reflectivity(np.array([math.cos(t)]))[0] == pytest.approx(
            expected, rel=1e-12)
    # a glint: far brighter than any Lambertian surface face-on, gone a few lobe widths away
    assert specular_peak(mat) == pytest.approx(0.04 / (4 * m * m))
    assert specular_peak(mat) > 10
    assert mat.effective_reflectivity(np.array([math.cos(math.radians(15))]))[0] < 0.1


def test_retro_reflector_falls_linearly_to_its_acceptance_angle():
    mat = Material(retro_reflectivity=500.0, retro_acceptance_deg=40.0)
    theta = np.radians([0.0, 10.0, 20.0, 40.0, 50.0])
    np.testing.assert_allclose(mat.effective_reflectivity(np.cos(theta)),
                               500.0 * np.maximum(0, 1 - np.degrees(theta) / 40.0), rtol=1e-9)


def test_table_evaluates_each_hit_with_its_own_part():
    table = MaterialTable.from_materials([MATERIAL_LIBRARY["lambertian_10"],
                                          MATERIAL_LIBRARY["white_paint"]])
    part = np.array([0, 1, 1, 0])
    cos = np.array([1.0, 1.0, 0.5, 0.5])
    np.testing.assert_allclose(table.effective(part, cos), [0.1, 0.8, 0.4, 0.05])


def test_the_compiled_table_gives_the_numpy_bits(monkeypatch):
    """ρ_eff through the compiled passes (kernels.reflectance) equals the NumPy reference to
    the bit on 200,000 hits: diffuse, specular and retro-reflecting parts, cosines outside
    [0, 1], grazing hits whose lobe divides by zero (NaN in both), int16 and int64 parts."""
    pytest.importorskip("numba")
    rng = np.random.default_rng(22)
    table = MaterialTable.from_materials([
        Material(diffuse_reflectivity=0.3, specular_reflectance=0.5, specular_slope_deg=5.0),
        Material(diffuse_reflectivity=0.6),
        Material(diffuse_reflectivity=0.1, retro_reflectivity=3.0, retro_acceptance_deg=10.0),
        Material(diffuse_reflectivity=0.2, specular_reflectance=0.3, specular_slope_deg=20.0,
                 retro_reflectivity=1.0, retro_acceptance_deg=30.0)])
    cos = rng.uniform(-0.1, 1.1, 200_000)
    cos[:100], cos[100:200], cos[200:300] = 0.0, 1e-170, 1.0
    for part in (rng.integers(0, 4, cos.size).astype(np.int16),
                 rng.integers(0, 4, cos.size)):
        monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
        with np.errstate(all="ignore"):
            reference = table.effective(part, cos)
        monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
        compiled = table.effective(part, cos)
        assert np.isnan(reference).sum() > 0  # the grazing hits are in the test
        assert compiled.view(np.uint64).tolist() == reference.view(np.uint64).tolist()
    lambertian = MaterialTable.from_materials([MATERIAL_LIBRARY["lambertian_10"]])
    assert lambertian.effective(np.zeros(3, dtype=np.int16), np.array([1.0, 0.5, 0.0])) \
        .tolist() == [0.1, 0.05, 0.0]
    # a scalar and a grid of cosines keep their shapes, with each element's value (a scalar
    # failed on the specular lobe before)
    glossy = table.materials[3]
    grid = np.linspace(0.0, 1.0, 12).reshape(3, 4)
    flat = glossy.effective_reflectivity(grid.ravel())
    for kernels_mode in ("numpy", "numba"):
        monkeypatch.setenv("LIDARSIM_KERNELS", kernels_mode)
        assert glossy.effective_reflectivity(grid).shape == (3, 4)
        assert glossy.effective_reflectivity(grid).ravel().tolist() == flat.tolist()
        single = glossy.effective_reflectivity(0.5)
        assert np.shape(single) == () and float(single) == \
            glossy.effective_reflectivity(np.array([0.5]))[0]


def test_every_library_material_states_its_source():
    for name, mat in MATERIAL_LIBRARY.items():
        assert mat.source and mat.description, name


# ---- Envisat and the intensity column ----------------------------------------------------------
def test_envisat_parts_have_default_materials_and_intensity_follows_them():
    from lidarsim_core.models.builtin import ENVISAT_MATERIALS
    from lidarsim_core.models.envisat import ENVISAT_PARTS
    from lidarsim_core.scenario import demo_scenario

    assert set(ENVISAT_MATERIALS) == set(ENVISAT_PARTS)
    assert set(ENVISAT_MATERIALS.values()) <= set(MATERIAL_LIBRARY)
    sim = Simulation(demo_scenario(duration_s=0.05, detail="coarse", backend="numpy",
                                   noise=False))
    cloud = sim.run_frame(0)
    assert len(set(cloud["part"].tolist())) >= 2
    for part in np.unique(cloud["part"]):
        name = cloud.frame.part_names[part].split("/", 1)[1]
        mat = MATERIAL_LIBRARY[ENVISAT_MATERIALS[name]]
        sel = cloud["part"] == part
        expected = mat.effective_reflectivity(np.cos(cloud["incidence_angle"][sel]))
        np.testing.assert_allclose(cloud["intensity"][sel], expected, rtol=1e-6, err_msg=name)


@pytest.mark.parametrize("angle", [0.0, 30.0, 60.0])
def test_intensity_of_a_plate_is_rho_cos_incidence(angle):
    cloud = Simulation(_with_materials(scenario(PLATE, _tilted(angle)),
                                       {"plate": {"diffuse_reflectivity": 0.4}})).run_frame(0)
    assert len(cloud) > 100
    np.testing.assert_allclose(cloud["incidence_angle"], math.radians(angle), atol=0.36)
    np.testing.assert_allclose(cloud["intensity"], 0.4 * np.cos(cloud["incidence_angle"]),
                               rtol=1e-6)


def test_parts_without_material_use_the_default():
    cloud = Simulation(scenario(PLATE, _tilted(0))).run_frame(0)
    np.testing.assert_allclose(cloud["intensity"],
                               MATERIAL_LIBRARY["default"].diffuse_reflectivity
                               * np.cos(cloud["incidence_angle"]), rtol=1e-6)


def test_scenario_materials_by_name_inline_star_and_own_library():
    from lidarsim_core.scenario import scenario_from_dict

    base = scenario({"model": "envisat", "options": {"detail": "coarse"}},
                    {"position_m": [30, -8, 0]}).model_dump()
    base["targets"][0]["materials"] = {"*": "black_paint", "bus": "shiny",
                                       "solar_array": {"diffuse_reflectivity": 0.9}}
    base["materials"] = {"shiny": {"diffuse_reflectivity": 0.6, "specular_reflectance": 0.5}}
    sim = Simulation(scenario_from_dict(base))
    by_part = dict(zip(sim.part_names, sim.materials.materials))
    assert by_part["t/bus"].diffuse_reflectivity == 0.6
    assert by_part["t/bus"].specular_reflectance == 0.5
    assert by_part["t/solar_array"].diffuse_reflectivity == 0.9
    assert by_part["t/adapter_ring"] == MATERIAL_LIBRARY["black_paint"]


@pytest.mark.parametrize("materials, own, field, words", [
    ({"hull": "white_paint"}, {}, "targets.0.materials.hull", "no part named"),
    ({"plate": "unobtainium"}, {}, "targets.0.materials.plate", "unknown material"),
    ({"plate": {"diffuse_reflectivity": 1.5}}, {},
     "targets.0.materials.plate.diffuse_reflectivity", "1"),
    ({"plate": {"colour": 3}}, {}, "targets.0.materials.plate.colour", "unknown key"),
    ({}, {"white_paint": {"diffuse_reflectivity": 0.5}}, "materials.white_paint", "built-in"),
])
def test_bad_materials_name_the_field(materials, own, field, words):
    sc = scenario(PLATE, _tilted(0), materials=own)
    data = sc.model_dump()
    data["targets"][0]["materials"] = materials
    from lidarsim_core.scenario import scenario_from_dict

    with pytest.raises(ConfigError) as err:
        Simulation(scenario_from_dict(data))
    assert err.value.field == field and words in str(err.value)


# ---- mesh files -------------------------------------------------------------------------------
def _srgb_linear(v: float) -> float:
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def test_obj_mtl_colours_become_part_materials(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl dark\nKd 0.2 0.2 0.2\nnewmtl light\nKd 0.9 0.8 0.7\n")
    (tmp_path / "m.obj").write_text(
        "mtllib m.mtl\nv 0 -5 -5\nv 0 5 -5\nv 0 5 5\nv 0 -5 5\n"
        "v 1 -5 -5\nv 1 5 -5\nv 1 5 5\nusemtl dark\nf 1 2 3\nf 1 3 4\nusemtl light\nf 5 6 7\n")
    from lidarsim_core.scene.mesh import load_mesh_file

    mesh = load_mesh_file(tmp_path / "m.obj")
    mats = dict(zip(mesh.part_names, mesh.part_materials))
    # trimesh stores Kd as 8-bit sRGB; the reflectivity is the mean linear value
    dark = np.round(np.array([0.2] * 3) * 255) / 255
    assert mats["dark"]["diffuse_reflectivity"] == pytest.approx(
        np.mean([_srgb_linear(v) for v in dark]), abs=1e-6)
    light = np.round(np.array([0.9, 0.8, 0.7]) * 255) / 255
    assert mats["light"]["diffuse_reflectivity"] == pytest.approx(
        np.mean([_srgb_linear(v) for v in light]), abs=1e-6)
    # and the simulation uses them
    sc = scenario({"path": str(tmp_path / "m.obj")}, {"position_m": [10, 0, 0]})
    cloud = Simulation(sc).run_frame(0)
    dark_part = cloud.frame.part_names.index("t/dark")
    sel = cloud["part"] == dark_part
    assert sel.sum() > 50
    np.testing.assert_allclose(cloud["intensity"][sel],
                               mats["dark"]["diffuse_reflectivity"]
                               * np.cos(cloud["incidence_angle"][sel]), rtol=1e-6)


def test_glb_base_colour_and_colourless_stl(tmp_path):
    import trimesh

    from lidarsim_core.scene.mesh import load_mesh_file

    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(
        material=trimesh.visual.material.PBRMaterial(baseColorFactor=[255, 255, 255, 255]))
    trimesh.Scene({"panel": box}).export(tmp_path / "b.glb")
    mesh = load_mesh_file(tmp_path / "b.glb")
    assert mesh.part_materials[0]["diffuse_reflectivity"] == pytest.approx(1.0)
    trimesh.creation.box().export(tmp_path / "b.stl")
    assert load_mesh_file(tmp_path / "b.stl").part_materials == ()


def test_material_from_colour_is_the_mean_linear_rgb():
    assert material_from_colour([0, 0, 0])["diffuse_reflectivity"] == 0.0
    assert material_from_colour([1, 1, 1])["diffuse_reflectivity"] == 1.0
    assert material_from_colour([0.5, 0.5, 0.5])["diffuse_reflectivity"] == pytest.approx(
        0.214041, abs=1e-6)


def test_scaled_mesh_keeps_its_materials():
    sc = scenario({"model": "envisat", "options": {"detail": "coarse"}, "scale": 0.5},
                  {"position_m": [20, -4, 0]})
    sim = Simulation(sc)
    by_part = dict(zip(sim.part_names, sim.materials.materials))
    assert by_part["t/solar_array"] == MATERIAL_LIBRARY["solar_cell_glass"]

