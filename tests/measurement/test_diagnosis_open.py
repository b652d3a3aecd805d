"""Open-world diagnosis (issue 12): effects the library lacks, an honest verdict, the missing term proposed.

The out-of-library effects are user effect files written here; the campaigns are simulated in a
subprocess that loads them, and diagnosed in this process, which never loads them (they are not
candidates, not even known).  Campaigns: beta +-5 %, K +-1 %, sensor noise and quantization.
The default run checks the crank spring end to end (verdict, what the residual follows, the proposed
term within 30 %, the effect file that ``ehas compare --effects-path`` fits) and a few clean and
Coulomb campaigns; the sweeps over every out-of-library effect and seed, 20 clean seeds, pairs,
long logs and confidence-interval coverage are marked slow.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from ehas_env.cli.campaign import simulate_campaign
from ehas_env.measurement.campaign import Campaign, read_campaign, validate_run
from ehas_env.measurement.diagnosis import diagnose_open

OOL = {
    "crank_spring": textwrap.dedent('''
"""A centring spring on the crank."""
from ehas_env.physics.effects import Effect, Param


class CrankSpring(Effect):
    name = "crank_spring"
    title = "centring spring on the crank"
    params = (Param("k", "N m/rad", 400.0, (0.0, 1.0e5), "spring rate", typical=(200.0, 800.0)),)
    main_param = "k"
    explanation = "A spring pulls the crank back to 0 deg: torque -k theta."
    signature = "load residual in phase with position"

    @staticmethod
    def crank_torque(theta, k):
        return -(k * theta)
'''),
    "direction_gain": textwrap.dedent('''
"""A valve whose flow gain differs for the two spool directions."""
from ehas_env.physics.effects import Effect, Param


class DirectionGain(Effect):
    name = "direction_gain"
    title = "valve flow gain differing per spool direction"
    params = (Param("g", "-", 0.12, (-0.9, 0.9), "extra relative gain for positive current", typical=(0.05, 0.2)),)
    main_param = "g"
    chain_order = 50
    explanation = "The positive spool direction passes (1 + g) times the flow of the negative one."
    signature = "flow and current residuals that follow the current only while it is positive"

    @staticmethod
    def valve_current(i, g):
        return i * (1.0 + g) if i > 0.0 else i
'''),
    "single_rod": textwrap.dedent('''
"""A single-rod actuator: the B side (annulus) has a smaller area than the A side."""
from ehas_env.physics.effects import Effect, Param


class SingleRod(Effect):
    name = "single_rod"
    title = "single-rod actuator (area ratio)"
    params = (Param("alpha", "-", 0.7, (0.2, 1.0), "annulus area over bore area", typical=(0.6, 0.9)),)
    main_param = "alpha"
    explanation = "Force A p_A - alpha A p_B; chamber B sees alpha A of the piston's motion."
    signature = "load residual following the B pressure; asymmetric pressures"

    @staticmethod
    def piston_force(pb, area, alpha):
        return (1.0 - alpha) * area * pb

    @staticmethod
    def chamber_flows(v, area, alpha):
        return 0.0, -(1.0 - alpha) * area * v
'''),
    "return_pressure": textwrap.dedent('''
"""Back-pressure in the return line: the tank side of the valve is not at 0."""
import math

from ehas_env.physics.effects import Effect, Param


class ReturnPressure(Effect):
    name = "return_pressure"
    title = "return line back-pressure"
    params = (Param("p_t", "bar", 15.0, (0.0, 80.0), "return line pressure", typical=(5.0, 25.0), si=1.0e5),)
    main_param = "p_t"
    explanation = "The outflow land sees p - p_t instead of p."
    signature = "outflow smaller, chamber pressures higher"

    @staticmethod
    def chamber_flows(qc, pa, pb, rated_drop, p_t):
        half = 0.5 * rated_drop
        if qc >= 0.0:
            return 0.0, -qc * (math.sqrt(max(pb - p_t, 0.0) / half) - math.sqrt(max(pb, 0.0) / half))
        return -qc * (math.sqrt(max(pa - p_t, 0.0) / half) - math.sqrt(max(pa, 0.0) / half)), 0.0
'''),
    "disc_drag": textwrap.dedent('''
"""Air and oil drag on the disc stack: torque growing with the square of the speed."""
from ehas_env.physics.effects import Effect, Param


class DiscDrag(Effect):
    name = "disc_drag"
    title = "quadratic drag on the discs"
    params = (Param("c", "N m s^2/rad^2", 20.0, (0.0, 1.0e4), "drag coefficient", typical=(5.0, 40.0)),)
    main_param = "c"
    explanation = "Torque -c omega |omega|."
    signature = "load residual following omega |omega|"

    @staticmethod
    def crank_torque(omega, c):
        return -(c * omega * abs(omega))
'''),
    "worn_bore": textwrap.dedent('''
"""Seal friction rising toward the stroke ends (a worn bore)."""
import math

from ehas_env.physics.effects import Effect, Param


class WornBore(Effect):
    name = "worn_bore"
    title = "position-dependent seal friction"
    params = (Param("F0", "N", 200.0, (0.0, 3000.0), "friction at mid-stroke", typical=(100.0, 400.0)),
              Param("g", "-", 3.0, (0.0, 20.0), "rise toward the ends: F0 (1 + g (x/35 mm)^2)", typical=(1.0, 5.0)))
    main_param = "F0"
    smooth = False
    explanation = "Friction F0 (1 + g (x / 35 mm)^2) opposing the motion."
    signature = "friction steps larger at large angles"

    @staticmethod
    def piston_force(x, v, v_tanh, F0, g):
        return -(F0 * (1.0 + g * (x / 0.035) ** 2) * math.tanh(v / v_tanh))
'''),
}
#: hidden magnitudes per effect (also outside the files' typical ranges) and seeds
OOL_CASES = {
    "crank_spring": [{"k": 400.0}, {"k": 150.0}, {"k": 1100.0}],
    "direction_gain": [{"g": 0.12}, {"g": 0.3}],
    "single_rod": [{"alpha": 0.7}, {"alpha": 0.5}],
    "return_pressure": [{"p_t": 15.0}, {"p_t": 40.0}],
    "disc_drag": [{"c": 20.0}, {"c": 80.0}],
    "worn_bore": [{"F0": 200.0, "g": 3.0}, {"F0": 500.0, "g": 8.0}],
}
POS_ONLY = ("t", "current_mA", "theta_deg", "theta_ref_deg")
SEED = 12000

GEN = """
import json, sys
from ehas_env.physics.effects import load_effects_path
load_effects_path(sys.argv[1])
from ehas_env.cli.campaign import write_simulated_campaign
for spec in json.loads(sys.argv[2]):
    write_simulated_campaign(spec["out"], spec["effects"], seed=spec["seed"], perturb=True,
                             duration=spec.get("duration", 3.0), overwrite=True)
"""


def generate(effects_dir, specs):
    """Simulate campaigns with the user effects in a separate process (this one never loads them)."""
    subprocess.run([sys.executable, "-c", GEN, str(effects_dir), json.dumps(specs)], check=True,
                   capture_output=True, text=True)


@pytest.fixture(scope="module")
def ool_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("user_effects")
    for name, text in OOL.items():
        (d / f"{name}.py").write_text(text)
    return d


def memory_campaign(effects, seed, *, duration=3.0, position_only=False):
    runs, truth = simulate_campaign(effects, seed=seed, perturb=True, duration=duration, valve=not position_only)
    if position_only:
        runs = [(n, {k: v for k, v in c.items() if k in POS_ONLY}, m) for n, c, m in runs]
    return Campaign(None, [validate_run(n, c, m) for n, c, m in runs]), truth


def check_unexplained(res, name, truth):
    assert res.verdict == "unexplained", (name, res.cost_all, res.run_costs)
    doc = res.to_json()
    u = doc["unexplained"]
    assert u is not None and u["residual_x_noise"] > 1.5 and u["follows"]
    assert json.loads(json.dumps(doc)) == doc
    return u


def test_crank_spring_is_unexplained_followed_by_position_and_proposed(ool_dir, tmp_path, capsys):
    from ehas_env.cli.main import main

    camp_dir = tmp_path / "spring"
    generate(ool_dir, [{"out": str(camp_dir), "effects": {"crank_spring": {"k": 400.0}}, "seed": SEED + 1}])
    truth = json.loads((camp_dir / "truth.json").read_text())
    out, eff = tmp_path / "d.json", tmp_path / "mine" / "centring.py"
    assert main(["diagnose", str(camp_dir), "--json", str(out), "--quiet", "--write-effect", str(eff)]) == 0
    text = capsys.readouterr().out
    assert "verdict: unexplained" in text and "nothing beats noise" not in text
    doc = json.loads(out.read_text())
    u = doc["unexplained"]
    assert u["follows"][0] == "theta"
    assert u["residual_x_noise"] > 5
    p = u["proposal"]
    assert p["where"] == ["crank_torque"]
    (term,) = [t for t in p["terms"] if t["form"] == "theta"]
    assert -term["value"] == pytest.approx(truth["effects"]["crank_spring"]["k"], rel=0.3)
    assert p["validation"]["residual_x_noise_all_after"] <= 2.0
    assert term["ci95"][0] <= term["value"] <= term["ci95"][1]
    # the written effect file works in compare (another process: the file is a new effect)
    r = subprocess.run([sys.executable, "-m", "ehas_env.cli.main", "compare", str(camp_dir), "--effects-path",
                        str(eff.parent), "--effects", "centring", "--fit"], capture_output=True, text=True)
    if r.returncode != 0:  # the console entry point, when the module has no __main__
        r = subprocess.run(["ehas", "compare", str(camp_dir), "--effects-path", str(eff.parent), "--effects",
                            "centring", "--fit"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    import re

    m = re.search(r"overall fit: ([0-9.]+) % -> ([0-9.]+) %", r.stdout)
    assert m and float(m.group(2)) > float(m.group(1)) + 20


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(OOL_CASES))
def test_out_of_library_effects_are_unexplained(name, ool_dir, tmp_path):
    specs = [{"out": str(tmp_path / f"c{j}"), "effects": {name: vals}, "seed": SEED + 100 + 7 * j}
             for j, vals in enumerate(OOL_CASES[name])]
    generate(ool_dir, specs)
    for spec in specs:
        camp = read_campaign(spec["out"])
        truth = json.loads((tmp_path / spec["out"] / "truth.json").read_text())
        res = diagnose_open(camp)
        u = check_unexplained(res, name, truth)
        print(f"\n{name} {spec['effects']}: x{u['residual_x_noise']:.2f}, follows {u['follows'][:3]}, "
              f"kept {list(res.model.effects)}, proposal {u['proposal'] and u['proposal']['equation']}, "
              f"after {u['proposal'] and u['proposal']['validation']['residual_x_noise_all_after']}")
        if name == "crank_spring":
            assert u["follows"][0] == "theta"
            p = u["proposal"]
            k = sum(-t["value"] * (1.0 if t["form"] == "theta" else 0.05**2) for t in p["terms"]
                    if t["form"] in ("theta", "x"))
            assert k == pytest.approx(spec["effects"][name]["k"], rel=0.3)
            assert p["validation"]["residual_x_noise_all_after"] <= 2.0


@pytest.mark.parametrize("seed", range(3))
def test_clean_campaigns_are_explained(seed):
    camp, _ = memory_campaign({}, SEED + 500 + seed, duration=2.0, position_only=seed == 2)
    res = diagnose_open(camp, propose=False)
    assert res.verdict == "explained", (res.cost_all, res.run_costs, res.kept)
    assert res.to_json()["unexplained"] is None


@pytest.mark.slow
def test_clean_campaigns_over_20_seeds_rarely_unexplained():
    for position_only in (False, True):
        bad = []
        for seed in range(20):
            camp, _ = memory_campaign({}, SEED + 600 + seed, position_only=position_only)
            res = diagnose_open(camp, propose=False)
            if res.verdict != "explained":
                bad.append((seed, round(res.cost_all, 3), res.kept))
        print(f"\nclean, position only {position_only}: unexplained {len(bad)}/20 {bad}")
        assert len(bad) <= 1, bad


def test_position_only_coulomb_gives_coulomb_first():
    camp, truth = memory_campaign({"coulomb_friction": {"Fc": 700.0}}, SEED + 700, duration=2.0, position_only=True)
    res = diagnose_open(camp, propose=False)
    top = res.first.ranking[0]
    assert top.effect in ("coulomb_friction", "stribeck_friction")
    assert top.params["Fc"] == pytest.approx(700.0, rel=0.3)
    assert res.kept and res.kept[0] == top.effect


@pytest.mark.slow
@pytest.mark.parametrize("pair", [{"coulomb_friction": {"Fc": 380.0}, "valve_null_bias": {"i_bias": -0.45}},
                                  {"transport_delay": {"tau": 0.004}, "valve_null_bias": {"i_bias": 0.6}},
                                  {"viscous_friction": {"b": 6000.0}, "internal_leakage": {"C_leak": 3e-12}}])
def test_pairs_are_both_found_and_nothing_third(pair):
    camp, truth = memory_campaign(pair, SEED + 800 + len(str(pair)), duration=3.0)
    res = diagnose_open(camp, propose=False)
    assert set(res.model.effects) == set(pair), [(s.effect, s.kept, s.reason) for s in res.steps]
    from ehas_env.physics.effects import get_effect

    for n, vals in pair.items():
        key = get_effect(n).main_param
        assert res.model.effects[n][key] == pytest.approx(vals[key], rel=0.3)


@pytest.mark.slow
def test_confidence_intervals_cover_the_truth():
    from ehas_env.physics.effects import get_effect

    cases = [("coulomb_friction", {"Fc": 250.0}), ("viscous_friction", {"b": 3000.0}),
             ("valve_null_bias", {"i_bias": 0.4}), ("internal_leakage", {"C_leak": 2e-12}),
             ("piston_mass", {"m": 40.0}), ("coulomb_friction", {"Fc": 900.0}), ("viscous_friction", {"b": 9000.0}),
             ("transport_delay", {"tau": 0.005}), ("valve_deadband", {"d": 0.8}), ("external_leakage", {"C_ext": 1e-12})]
    hits = total = 0
    for j, (n, vals) in enumerate(cases):
        camp, truth = memory_campaign({n: vals}, SEED + 900 + j, duration=3.0)
        res = diagnose_open(camp, propose=False)
        for (eff, pname), (lo, hi) in res.ci.items():
            if eff == n:
                total += 1
                hits += lo <= vals[pname] <= hi
    print(f"\nCI coverage {hits}/{total}")
    assert total >= len(cases) - 1 and hits >= 0.9 * total


@pytest.mark.slow
def test_long_logs_diagnose_in_at_most_twice_the_time():
    import time

    res = {}
    for dur in (3.0, 30.0):
        camp, truth = memory_campaign({"coulomb_friction": {"Fc": 420.0}}, SEED + 1000, duration=dur)
        t0 = time.perf_counter()
        res[dur] = (diagnose_open(camp, propose=False), time.perf_counter() - t0)
    (short, ts), (long, tl) = res[3.0], res[30.0]
    print(f"\n3 s runs: {ts:.1f} s, 30 s runs: {tl:.1f} s")
    assert tl <= 2.0 * ts
    assert list(long.model.effects) == list(short.model.effects) == ["coulomb_friction"]
    assert abs(long.model.effects["coulomb_friction"]["Fc"] - 420) <= abs(short.model.effects["coulomb_friction"]["Fc"] - 420) + 5
