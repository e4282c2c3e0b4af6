"""Network factor NF_s of a sample (`asphalt-nscd harmonic-transfer`) and the transfer
correction of `run-2pb --network-factor-json`: NF_s is real and independent of the law and
the frequency; the corrected time-domain test returns the law's |E*|; bad JSON is rejected."""

from cli_options import set_options
import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.rheology import law_file
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import read_sample, specimen_geometry_mm, write_sample
from asphalt_nscd.harmonic.response import harmonic_rows
from asphalt_nscd.harmonic.solver import HarmonicSystem
from asphalt_nscd.harmonic.transfer import corrected_law, network_factor, read_transfer_json, unit_elastic_law
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.laws import GeneralizedBurgers

#: a solid law with a fast Kelvin-Voigt unit (Pa, Pa s): steady state within a cycle at 1 Hz
SOLID = GeneralizedBurgers(Em=3e7, eta_m=np.inf, Ek=(5e7,), eta_k=(5e5,), E_inf=1e6)
LAWS = (
    unit_elastic_law(),
    GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5),
    GeneralizedBurgers(Em=2.0e9, eta_m=5e8, Ek=(4e9, 1e9), eta_k=(5e7, 1e9), E_inf=1e6),
    SOLID,
)


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    path = tmp_path_factory.mktemp("transfer") / "s1.h5"
    write_sample(path, lattice_sample(30, seed=2, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    return path


@pytest.fixture(scope="module")
def transfer(sample):
    out = sample.with_name("s1_transfer.json")
    assert main(["harmonic-transfer", "--sample", str(sample), "-o", str(out)]) == 0
    return out


@pytest.mark.parametrize("kinematics, head", [("contact", "free"), ("barycentre", "clamped")])
def test_network_factor_is_real_and_independent_of_law_and_frequency(sample, kinematics, head):
    """One complex LU of E*(w) G per (law, f) (solver 'direct', independent of the real
    factorisation of the 'reuse' path): the same real factor for every law and frequency."""
    system = HarmonicSystem(network_from_sample(read_sample(sample)), bond_kinematics=kinematics, head_rotation=head)
    geometry = specimen_geometry_mm(read_sample(sample))
    ref = network_factor(system, geometry)  # unit elastic law, 1 Hz, reuse
    assert ref.imag == 0.0 and ref.real > 0
    for law in LAWS:
        for f in (0.1, 3.0, 40.0):
            nf = network_factor(system, geometry, law=law, frequency_Hz=f, solver="direct")
            assert nf.real == pytest.approx(ref.real, rel=1e-6)
            assert abs(nf.imag) < 1e-6 * ref.real
    # the factor is the EN 12697-26 one of the harmonic rows without inertia
    rows = harmonic_rows(system, LAWS[1], 20.0, [0.1, 10.0], geometry, inertia="none")
    for r in rows:
        assert r["network_factor"] == pytest.approx(ref.real, rel=1e-9)
        assert abs(r["phase_difference_deg"]) < 1e-6


def test_network_factor_depends_on_the_kinematics(sample):
    """The factor is a property of the discrete model: the barycentre kinematics stiffens bending."""
    geometry = specimen_geometry_mm(read_sample(sample))
    nf = {
        k: network_factor(
            HarmonicSystem(network_from_sample(read_sample(sample)), bond_kinematics=k, head_rotation=h), geometry
        ).real
        for k, h in (("contact", "free"), ("barycentre", "clamped"))
    }
    assert nf["barycentre"] > 1.5 * nf["contact"]


def test_cli_writes_the_transfer_json(sample, transfer):
    obj = json.loads(transfer.read_text())
    system = HarmonicSystem(network_from_sample(read_sample(sample)))
    assert obj["network_factor"] == pytest.approx(
        network_factor(system, specimen_geometry_mm(read_sample(sample))).real, rel=1e-12
    )
    assert obj["sample"] == "s1" and obj["bond_kinematics"] == "contact" and obj["head_rotation"] == "free"
    assert obj["nu"] == 0.35 and obj["inertia"] == "none" and "network_factor" in obj["units"]
    assert abs(obj["imag_relative"]) < 1e-12 and obj["residual"] < 1e-10
    assert (
        read_transfer_json(transfer, sample="s1", bond_kinematics="contact", head_rotation="free", nu=0.35)[
            "network_factor"
        ]
        == obj["network_factor"]
    )


def _edit(obj, **kw):
    return {**obj, **kw}


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda o: "{oops", "not valid JSON"),
        (lambda o: [1, 2], "expected a JSON object"),
        (lambda o: {k: v for k, v in o.items() if k != "network_factor"}, r"missing key\(s\) \['network_factor'\]"),
        (lambda o: _edit(o, network_factor=0.0), "key 'network_factor': expected a positive finite number"),
        (lambda o: _edit(o, network_factor=-1.2), "key 'network_factor'"),
        (lambda o: _edit(o, network_factor="1.1"), "key 'network_factor'"),
        (lambda o: _edit(o, network_factor=True), "key 'network_factor'"),
        (lambda o: _edit(o, bond_kinematics="glue"), "key 'bond_kinematics': expected one of"),
        (lambda o: _edit(o, head_rotation="spinning"), "key 'head_rotation'"),
        (lambda o: _edit(o, nu="0.35"), "key 'nu': expected a number"),
    ],
)
def test_bad_transfer_json_raises_input_error(tmp_path, transfer, edit, message):
    bad = tmp_path / "bad.json"
    out = edit(json.loads(transfer.read_text()))
    bad.write_text(out if isinstance(out, str) else json.dumps(out))
    with pytest.raises(InputError, match=message) as err:
        read_transfer_json(bad)
    assert str(err.value).startswith(str(bad))


def test_transfer_json_must_match_the_run(transfer, tmp_path):
    for kw, key in (
        ({"sample": "s2"}, "sample"),
        ({"bond_kinematics": "barycentre"}, "bond_kinematics"),
        ({"head_rotation": "clamped"}, "head_rotation"),
        ({"nu": 0.3}, "nu"),
    ):
        with pytest.raises(InputError, match=f"key '{key}': the factor was computed for"):
            read_transfer_json(transfer, **kw)
    with pytest.raises(InputError, match="nope.json: cannot read"):
        read_transfer_json(tmp_path / "nope.json")


def test_corrected_law_divides_the_complex_modulus_by_the_network_factor(transfer):
    nf = read_transfer_json(transfer)["network_factor"]
    law, got = corrected_law(LAWS[1], transfer, sample="s1", bond_kinematics="contact", head_rotation="free", nu=0.35)
    assert got == nf and nf != 1.0
    for omega in (0.3, 60.0):
        assert law.complex_modulus(omega) == pytest.approx(LAWS[1].complex_modulus(omega) / nf, rel=1e-12)
    with pytest.raises(InputError, match="key 'sample'"):
        corrected_law(LAWS[1], transfer, sample="s2")


SETTINGS = json.dumps(
    {
        "n_cycles": 2,
        "dt_policy": "steps_per_cycle",
        "steps_per_cycle": 40,
        "dt_max_s": 1.0,
        "checkpoint_every": 0,
        "profile_instants": 4,
    }
)


def _run(sample, tmp_path, name, extra, settings=SETTINGS):
    return main(
        [
            "run-2pb",
            "--sample",
            str(sample),
            "--sample-name",
            "s1",
            "--law-json",
            str(tmp_path / "laws.json"),
            *extra,
            "--temperature",
            "20",
            "--frequency",
            "1",
            *set_options(settings),
            "--no-progress",
            "--mode",
            "extended",
            "-o",
            str(tmp_path / f"{name}.h5"),
            "--row",
            str(tmp_path / f"{name}.csv"),
        ]
    )


def test_corrected_time_domain_run_matches_the_law(sample, transfer, tmp_path):
    """Time-domain NSCD test at 1 Hz: without the correction |E*| = NF_s |E*_law|; with it
    |E*| = |E*_law| within 1 % (inertia and time integration are small at 1 Hz)."""
    (tmp_path / "laws.json").write_text(json.dumps(law_file.to_json({20.0: SOLID.scaled(1e-6)})))
    nf = json.loads(transfer.read_text())["network_factor"]
    assert abs(nf - 1) > 0.3  # the lattice is far from NF = 1: the test can fail
    assert _run(sample, tmp_path, "raw", []) == 0
    assert _run(sample, tmp_path, "cor", ["--network-factor-json", str(transfer)]) == 0
    raw, cor = pd.read_csv(tmp_path / "raw.csv").iloc[0], pd.read_csv(tmp_path / "cor.csv").iloc[0]
    e = SOLID.complex_modulus(2 * np.pi * 1.0) * 1e-6
    assert raw["E_norm_MPa"] == pytest.approx(nf * abs(e), rel=0.01)
    assert cor["E_norm_MPa"] == pytest.approx(abs(e), rel=0.01)
    assert cor["phase_deg"] == pytest.approx(np.degrees(np.angle(e)), abs=0.05)
    assert cor["transfer_network_factor"] == nf and cor["transfer_json"] == str(transfer)
    assert "transfer_network_factor" not in raw.index
    assert cor["Em_MPa"] == pytest.approx(SOLID.Em * 1e-6)  # the row keeps the macro law


def test_run_2pb_rejects_a_mismatched_or_bad_transfer_json(sample, transfer, tmp_path, capsys):
    (tmp_path / "laws.json").write_text(json.dumps(law_file.to_json({20.0: SOLID.scaled(1e-6)})))
    clamped = json.dumps({**json.loads(SETTINGS), "head_rotation": "clamped"})
    assert _run(sample, tmp_path, "x", ["--network-factor-json", str(transfer)], settings=clamped) == 2
    assert "key 'head_rotation': the factor was computed for 'free'" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**json.loads(transfer.read_text()), "network_factor": None}))
    assert _run(sample, tmp_path, "x", ["--network-factor-json", str(bad)]) == 2
    assert f"{bad}: key 'network_factor'" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
