"""Sample preparation: PSD counts, lattice, cut, flip, shrink, density, bonds (no dynamics)."""

import numpy as np
import pytest

from asphalt_nscd.io import InputError
from asphalt_nscd.sample import geometry, psd, settings
from asphalt_nscd.sample.prepare import counts_table, sphere_population


def test_class_fractions_from_table1():
    d, f = psd.class_fractions(cut_mm=2.0)
    np.testing.assert_allclose(d * 1e3, [2, 4, 6.3, 8, 10])
    # mass between sieves: 13, 14, 17, 15, 10 % of the 69 % above 2 mm
    np.testing.assert_allclose(f, np.array([13, 14, 17, 15, 10]) / 69)
    d, f = psd.class_fractions(cut_mm=6.3, class_diameter="upper")
    np.testing.assert_allclose(d * 1e3, [8, 10, 12.5])
    np.testing.assert_allclose(f, np.array([17, 15, 10]) / 42)


def test_sphere_counts_arithmetic():
    d = np.array([2e-3, 4e-3])
    n = psd.sphere_counts(1e-6, d, [0.5, 0.5])
    v = np.pi * d**3 / 6
    np.testing.assert_array_equal(n, np.rint(0.5e-6 / v))
    with pytest.raises(ValueError):
        psd.sphere_counts(0.0, d, [0.5, 0.5])


def test_paper_rule_near_table2():
    d, n, volume = sphere_population(settings.merge(settings.DEFAULTS, {}))
    # solid_fraction 0.7 x 250 x 25 x 60 mm^3
    assert volume == pytest.approx(0.7 * 0.25 * 0.025 * 0.06)
    np.testing.assert_array_equal(n, [11807, 1589, 494, 213, 73])
    table = counts_table(settings.merge(settings.DEFAULTS, {}))
    assert (table["rel_diff_pct"].abs() < 3.0).all()


def test_scale_changes_counts_by_cube():
    base = settings.merge(settings.DEFAULTS, {"psd": {"cut_mm": 6.3}})
    half = settings.merge(settings.DEFAULTS, {"psd": {"cut_mm": 6.3}, "scale": 0.5})
    _, n1, v1 = sphere_population(base)
    _, n2, v2 = sphere_population(half)
    assert v2 == pytest.approx(v1 / 8)
    np.testing.assert_allclose(n2, n1 / 8, atol=0.5)
    geo = settings.scaled_geometry(half)
    assert geo["h"] == pytest.approx(0.125) and geo["B"] == pytest.approx(0.028)
    assert geo["sample_mass"] == pytest.approx(0.6 / 8)
    assert geo["lattice"] == pytest.approx(0.010)  # sphere sizes are not scaled


def test_unknown_key_is_an_input_error():
    with pytest.raises(InputError, match="psd.*cut"):
        settings.merge(settings.DEFAULTS, {"psd": {"cutt_mm": 2}})


def test_lattice_placement_no_overlap_and_in_box():
    rng = np.random.default_rng(3)
    r = np.repeat([1e-3, 2e-3, 3.15e-3, 5e-3], [200, 40, 20, 10])
    box = (0.1, 0.025, 0.5)
    p = geometry.lattice_positions(r, box, 0.01, rng)
    assert geometry.max_overlap(p, r) < 1e-12
    assert np.all(p - r[:, None] >= -1e-15) and np.all(p + r[:, None] <= np.array(box) + 1e-15)
    # deterministic for a seed, different for another
    p2 = geometry.lattice_positions(r, box, 0.01, np.random.default_rng(3))
    np.testing.assert_array_equal(p, p2)
    p3 = geometry.lattice_positions(r, box, 0.01, np.random.default_rng(4))
    assert not np.allclose(p, p3)
    with pytest.raises(ValueError, match="box height"):
        geometry.lattice_positions(r, (0.1, 0.025, 0.02), 0.01, rng)
    with pytest.raises(ValueError, match="lattice cell"):
        geometry.lattice_positions(r, box, 0.008, rng)


def test_trapezoid_cut_by_barycentre():
    trap = geometry.Trapezoid(B=0.056, b=0.025, e=0.025, h=0.25)
    assert trap.volume == pytest.approx(0.5 * (0.056 + 0.025) * 0.025 * 0.25)
    pts = np.array(
        [
            [0.0, 0.0, 0.1],  # centre line
            [0.027, 0.0, 0.001],  # near base corner, inside (w/2 = 27.9 mm)
            [0.027, 0.0, 0.249],  # near head, outside (w/2 = 12.6 mm)
            [0.0125, 0.0, 0.25],  # head corner, on the boundary
            [0.0, 0.013, 0.1],  # outside in thickness
            [0.0, 0.0, -1e-4],  # below base
        ]
    )
    np.testing.assert_array_equal(trap.contains(pts), [True, True, False, True, False, False])
    # Monte-Carlo: the fraction of uniform points inside = trapezoid / bounding box volume
    rng = np.random.default_rng(0)
    box_pts = rng.random((200_000, 3)) * [0.056, 0.025, 0.25] - [0.028, 0.0125, 0.0]
    frac = trap.contains(box_pts).mean()
    assert frac == pytest.approx(trap.volume / (0.056 * 0.025 * 0.25), abs=0.005)


def test_flip_is_a_rotation_to_the_specimen_frame():
    # deposition frame: x along the box (-> specimen z), z up (-> specimen -x about zc)
    p = np.array([[0.0, 0.0, 0.0], [0.25, 0.025, 0.06], [0.1, 0.0125, 0.03]])
    q = geometry.to_specimen_frame(p, zc=0.03, width=0.025)
    np.testing.assert_allclose(q, [[0.03, -0.0125, 0.0], [-0.03, 0.0125, 0.25], [0.0, 0.0, 0.1]])
    # distances preserved and orientation kept (det +1)
    a = geometry.to_specimen_frame(np.eye(3), 0.0, 0.0) - geometry.to_specimen_frame(np.zeros((1, 3)), 0.0, 0.0)
    assert np.linalg.det(a) == pytest.approx(1.0)


def test_shrink_removes_ten_percent_of_volume_and_density_gives_mass():
    r = np.array([1e-3, 2e-3, 5e-3])
    rs = geometry.shrink_radii(r, 0.10)
    np.testing.assert_allclose(geometry.sphere_volume(rs), 0.9 * geometry.sphere_volume(r), rtol=1e-14)
    rho = geometry.density_for_mass(rs, 0.6)
    assert (rho * geometry.sphere_volume(rs)).sum() == pytest.approx(0.6, rel=1e-14)
    with pytest.raises(ValueError):
        geometry.shrink_radii(r, 1.0)


def test_bonds_only_below_d_min():
    r = np.array([1e-3, 1e-3, 1e-3, 2e-3])
    p = np.array(
        [
            [0.0, 0.0, 0.010],
            [0.0035, 0.0, 0.010],  # gap 1.5 mm to sphere 0 -> bond
            [0.0080, 0.0, 0.010],  # gap 2.5 mm to sphere 1 -> no bond
            [0.0, 0.0, 0.0035],  # gap 3.5 mm to sphere 0; 1.5 mm to bottom plate -> plate bond
        ]
    )
    point = np.array([[0, 0, 0.0], [0, 0, 0.012]])
    normal = np.array([[0, 0, 1.0], [0, 0, -1.0]])
    b = geometry.make_bonds(p, r, point, normal, d_min=2e-3)
    pairs = set(zip(b["i"].tolist(), b["j"].tolist()))
    # top plate at 12 mm: spheres 0-2 have gap 1 mm
    assert pairs == {(0, 1), (3, -1), (0, -2), (1, -2), (2, -2)}
    k = list(zip(b["i"], b["j"])).index((0, 1))
    assert b["delta0"][k] == pytest.approx(1.5e-3) and b["l0"][k] == pytest.approx(3.5e-3)
    assert b["r_min"][k] == pytest.approx(1e-3)
    k = list(zip(b["i"], b["j"])).index((3, -1))
    assert b["delta0"][k] == pytest.approx(1.5e-3) and b["l0"][k] == pytest.approx(3.5e-3)
    assert b["r_min"][k] == pytest.approx(2e-3)
    assert np.all(b["delta0"] < 2e-3)


def test_coordination_number():
    r = np.full(3, 1e-3)
    p = np.array([[0, 0, 0], [2e-3, 0, 0], [4.5e-3, 0, 0]])
    assert geometry.coordination_number(p, r, 1e-5) == pytest.approx(2 / 3)
    assert geometry.coordination_number(p, r, 1e-3) == pytest.approx(4 / 3)


def test_configs_match_schema_and_defaults():
    from pathlib import Path

    import jsonschema
    import yaml

    root = Path(__file__).resolve().parents[2]
    schema = yaml.safe_load((root / "workflow/schemas/sample.schema.yaml").read_text())
    jsonschema.Draft7Validator.check_schema(schema)

    def walk(d, sch, path=""):
        for k, v in d.items():
            assert k in sch["properties"], f"schema lacks {path}{k}"
            if isinstance(v, dict):
                walk(v, sch["properties"][k], f"{path}{k}.")

    walk(settings.DEFAULTS, schema)
    from asphalt_nscd import config

    for name in ("config", "smoke", "paper"):
        # the overlays merged over config/config.yaml, as Snakemake merges them
        section = config.load([root / f"config/{name}.yaml"], default=root / "config/config.yaml")["sample"]
        jsonschema.validate(section, schema)
        loaded = settings.load([root / "config/config.yaml", root / f"config/{name}.yaml"])
        assert loaded == settings.merge(settings.DEFAULTS, section) == section


def test_layer_height_surface_and_max():
    """A flat layer of unit spheres (tops at 2 mm) with one sphere resting on top: the top of
    the highest sphere jumps to 4 mm, the mean surface over 5 mm columns moves by one column's
    share only; a column with no sphere counts 0; the slice solid fraction of a cubic
    arrangement is pi/6."""
    from asphalt_nscd.sample.geometry import layer_height, solid_fraction_profile

    L, W, r = 0.02, 0.01, 1e-3
    x, y = np.meshgrid(np.arange(r, L, 2 * r), np.arange(r, W, 2 * r), indexing="ij")
    pos = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, r)])
    rad = np.full(x.size, r)
    assert layer_height(pos, rad, (L, W)) == pytest.approx(2 * r)
    top = np.vstack([pos, [[0.004, 0.004, 3 * r]]])
    rad2 = np.append(rad, r)
    assert layer_height(top, rad2, (L, W), "max") == pytest.approx(4 * r)
    # 4 x 2 columns of 5 mm: one of 8 is 2 mm higher
    assert layer_height(top, rad2, (L, W), "surface", 5e-3) == pytest.approx(2 * r + 2 * r / 8)
    # an empty half of the box halves the surface height
    half = pos[:, 0] < L / 2
    assert layer_height(pos[half], rad[half], (L, W), "surface", 5e-3) == pytest.approx(r)
    with pytest.raises(ValueError, match="measure"):
        layer_height(pos, rad, (L, W), "mean")
    z, phi = solid_fraction_profile(pos, rad, 2 * r, (L, W), dz=2 * r)
    assert phi == pytest.approx([np.pi / 6])
