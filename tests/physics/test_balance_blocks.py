"""The static terms at the model's balances (ehas_env.physics.balance_blocks) against analytic truth: a term beyond
a break at the smallest break is the library's viscous friction of slope c / S; beyond every value the run reaches it
is nothing; a chamber's term above a pressure the run never reaches is nothing, and one below it takes flow out
of that chamber alone."""
import numpy as np
import pytest

from ehas_env.physics import augment, balance_blocks
from ehas_env.physics.effects import REGISTRY, get_effect
from ehas_env.simulation.plant import Plant


def _run(effects):
    return Plant(disc_sets=3, effects=effects).simulate_closed_loop(amplitude_deg=20.0, freq_hz=2.0, cycles=3)


def test_every_kind_at_every_balance_place_is_registered_tried_and_worded():
    names = balance_blocks.balance_blocks()
    assert len(names) == sum(1 for k in balance_blocks.BALANCE_KINDS for p in balance_blocks.BALANCE_PLACES
                             if k.fits(p))
    assert set(names) <= set(augment.augmentations())  # the state stage tries them
    for n in names:
        cls = REGISTRY[n]
        assert cls.kind == "hypothesis" and cls.main_param == "c"
        words = cls.in_words({p.name: p.default or 0.3 * p.bounds[1] for p in cls.params},
                             {p.name: (0.1, 0.2) for p in cls.params})
        assert cls.where in words and "[" in words
        # a term of the quantity names it (a constant term is none: it names the balance alone)
        assert cls.balance_place.words in words or issubclass(cls, balance_blocks.Constant)
    # a constant term belongs to the balance: a place of one's own at a balance already there does not get it again
    crank_angle = balance_blocks.BalancePlace("crank_torque", "crank_angle", "theta", "rad", 0.5, (57.3, "deg"),
                                              "N m", 250.0, (1.0, "N m"), "t", "the crank torque balance",
                                              "the crank angle")
    assert not balance_blocks.Constant.fits(crank_angle) and balance_blocks.Beyond.fits(crank_angle)
    # nor the balances' other local quantities: one constant per balance, at its own quantity's place
    constants = [p for p in balance_blocks.BALANCE_PLACES if balance_blocks.Constant.fits(p)]
    assert len({(p.place, p.returns) for p in constants}) == len(constants) == 8


def test_a_place_the_model_cannot_compute_is_refused():
    # the rod joint's gap is computed for the joint's force alone, not where the chambers' flows are
    bad = balance_blocks.BalancePlace("chamber_flows", "gap_a", "gap", "m", 1.0e-3, (1.0e3, "mm"), "m^3/s", 1.0e-4,
                                      (60000.0, "L/min"), "t, 0.0", "chamber A's flow balance", "the joint's gap")
    with pytest.raises(ValueError, match="no 'gap' at chamber_flows"):
        balance_blocks.check_place(bad)
    with pytest.raises(ValueError, match="no 'gap' at chamber_flows"):
        balance_blocks.Beyond.at(bad)


def test_beyond_the_smallest_break_is_a_viscous_friction():
    place = get_effect("aug_beyond_piston_velocity").balance_place
    b = 3000.0  # N s/m
    k = get_effect("aug_beyond_piston_velocity").param("k").bounds[0]
    ref = _run({"viscous_friction": {"b": b}})
    blk = _run({"aug_beyond_piston_velocity": {"c": -b * place.q_span, "k": k}})
    base = _run({})
    # the two differ by b k sign(v) (1.5 N of a friction of hundreds): far less than the friction's own effect
    d_ref = np.max(np.abs(ref.theta_deg - base.theta_deg))
    assert d_ref > 0.05
    assert np.max(np.abs(blk.theta_deg - ref.theta_deg)) < 0.01 * d_ref


def test_beyond_what_the_run_reaches_is_nothing_and_below_it_acts():
    base = _run({})
    assert np.max(np.abs(np.radians(base.omega_deg_s))) < 10.0
    far = _run({"aug_beyond_crank_rate": {"c": -200.0, "k": 19.9}})  # 20 rad/s: twice the run's peak rate
    assert np.array_equal(far.theta_deg, base.theta_deg)
    near = _run({"aug_beyond_crank_rate": {"c": -200.0, "k": 2.0}})
    assert np.max(np.abs(near.theta_deg - base.theta_deg)) > 0.05


@pytest.mark.parametrize("c,d,twin", [
    (0.0, -250.0, ("aug_beyond_crank_rate", {"c": -250.0})),  # no slope within: a term beyond the break
    (-250.0, 0.0, ("aug_prop_crank_rate", {"c": -250.0})),  # no change of slope: a proportional term
    (-250.0, 250.0, ("aug_saturating_crank_rate", {"c": -250.0 * 2.0 / 10.0})),  # flat beyond: a saturation
])
def test_a_piecewise_linear_term_holds_the_proportional_the_beyond_and_the_saturating_ones(c, d, twin):
    """``Knee`` at the crank's torque balance, its break at 2 rad/s (the run reaches 8): with no slope within it is
    the term beyond the break, with no change of slope the proportional term, with the slope cancelled beyond the
    saturating term of level c k / S (S = 10 rad/s) -- the same crank angle to the last bits the integrator
    keeps (the three laws are written apart, each as its class says)."""
    base = _run({})
    knee = _run({"aug_knee_crank_rate": {"c": c, "d": d, "k": 2.0}})
    name, params = twin
    other = _run({name: {**params, **({} if name == "aug_prop_crank_rate" else {"k": 2.0})}})
    assert np.max(np.abs(knee.theta_deg - base.theta_deg)) > 0.03  # it acts
    np.testing.assert_allclose(knee.theta_deg, other.theta_deg, rtol=0.0, atol=1e-9)


def test_a_chamber_term_acts_on_its_own_chamber():
    base = _run({})
    never = _run({"aug_beyond_chamber_a": {"c": -4.0e-5, "k": 1.9e7}})  # above 190 bar: never reached
    assert np.array_equal(never.p_a_bar, base.p_a_bar)
    leak = _run({"aug_beyond_chamber_a": {"c": -4.0e-5, "k": 2.0e6}})  # a relief from A above 20 bar
    assert np.max(np.abs(leak.p_a_bar - base.p_a_bar)) > 1.0


@pytest.mark.parametrize("effect,c_bar", [("aug_saturating_supply", -20.0), ("aug_saturating_return", 20.0)])
def test_a_pressure_at_the_lands_meters_the_bench_flow_as_the_orifice_law_says(effect, c_bar):
    """On the flow bench (ports joined) the lands meter between the supply and the return pressure: the flow is
    qc sqrt((p_sup - p_ret) / rated drop).  A supply 20 bar lower at the lands, or a return 20 bar above the tank
    (a saturating term of the opening at its smallest break: a step of c at any opening), gives the flow of the
    bench at 20 bar less supply, sqrt((Ps - 20) / Ps) of it."""
    cmd = np.full(400, 10.0)  # mA: a steady opening
    k = get_effect(effect).param("k").bounds[0]
    base = Plant(disc_sets=1).simulate_valve_test(cmd, supply_bar=140.0)
    with_term = Plant(disc_sets=1, effects={effect: {"c": c_bar * 1e5, "k": k}}).simulate_valve_test(
        cmd, supply_bar=140.0)
    ratio = with_term.flow_lpm[-1] / base.flow_lpm[-1]
    assert ratio == pytest.approx(np.sqrt(120.0 / 140.0), rel=2e-3)


def test_a_constant_flow_at_a_land_is_the_chambers_and_the_meter_in_its_line_reads_it():
    """A land that passes a constant c more than the orifice law (``aug_const_land_a``) fills chamber A as a
    constant c into chamber A's balance (``aug_const_chamber_a``) does -- the same angle and pressures -- but the
    flow meter in line A, at the valve's port, sees it: its reading is c above the chamber term's at every sample;
    land B's term leaves the meter's reading alone."""
    c = -0.6 / 60000.0  # m^3/s: -0.6 L/min
    land = _run({"aug_const_land_a": {"c": c}})
    chamber = _run({"aug_const_chamber_a": {"c": c}})
    base = _run({})
    assert np.max(np.abs(land.p_a_bar - base.p_a_bar)) > 0.5  # it acts
    np.testing.assert_allclose(land.theta_deg, chamber.theta_deg, rtol=0, atol=1e-9)
    np.testing.assert_allclose(land.p_a_bar, chamber.p_a_bar, rtol=0, atol=1e-7)
    np.testing.assert_allclose(land.flow_lpm - chamber.flow_lpm, -0.6, rtol=0, atol=1e-6)
    other = _run({"aug_const_land_b": {"c": c}})
    chamber_b = _run({"aug_const_chamber_b": {"c": c}})
    np.testing.assert_allclose(other.p_b_bar, chamber_b.p_b_bar, rtol=0, atol=1e-7)
    np.testing.assert_allclose(other.flow_lpm, chamber_b.flow_lpm, rtol=0, atol=1e-9)


def test_a_land_term_of_its_own_flow_is_added_to_the_orifice_law():
    """The compiled model's ``lands`` with a cubic term at land B: the orifice law's flows, land B's with
    c (q_b / S)^3 added, land A's and the supply's draw unchanged."""
    from ehas_env.physics.baseline import land_flows

    c, span = 0.4 / 60000.0, get_effect("aug_cubic_land_b").balance_place.q_span
    plant = Plant(disc_sets=1, effects={"aug_cubic_land_b": {"c": c}})
    P = plant.param_vector
    for qc, pa, pb in [(2e-4, 120e5, 60e5), (-2e-4, 80e5, 130e5)]:
        qa, qb, qs = land_flows(qc, pa, pb, 210e5, 0.0, P[plant.model.IDX["rated_drop"]])
        got = plant.model.lands(plant.initial_state(0.0), qc, pa, pb, 210e5, P)
        assert got[0] == qa and got[2] == qs
        assert got[1] == pytest.approx(qb + c * (qb / span) ** 3, rel=1e-12)


def test_the_lands_at_the_supply_and_the_tank_are_the_book_model_bit_for_bit():
    """With no effect at the lands the model's flows are the book's law as it was (the tank at 0 bar exactly)."""
    from ehas_env.physics.baseline import land_flows

    m = Plant(disc_sets=1).model
    P = Plant(disc_sets=1).param_vector
    for qc, pa, pb in [(2e-4, 120e5, 60e5), (-2e-4, 80e5, 130e5), (0.0, 100e5, 100e5)]:
        assert m.lands(np.zeros(m.N_STATES), qc, pa, pb, 210e5, P) == land_flows(qc, pa, pb, 210e5, 0.0,
                                                                               P[m.IDX["rated_drop"]])


def test_the_docs_place_of_ones_own_is_the_crank_load_with_every_kind():
    """docs/effects-and-controllers.md's balance place of one's own, the file as the page shows it: loaded with
    effects_path it is an effect per kind at the crank's torque balance; a saturating term of the load pressure
    (a bearing's friction that rises with its load) moves a run, its sign with the load's, and opposes the motion
    where the load drives it.  In a child process: the example's effects must not join this session's registry."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    page = (root / "docs" / "effects-and-controllers.md").read_text(encoding="utf-8")
    shown = page.split("`docs/examples/my_kinds/crank_load_place.py`", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    assert shown == (root / "docs" / "examples" / "my_kinds" / "crank_load_place.py").read_text(encoding="utf-8")
    code = (
        "import numpy as np\n"
        "from ehas_env.simulation.plant import Plant\n"
        "from ehas_env.physics.balance_blocks import balance_blocks\n"
        "from ehas_env.physics.effects import get_effect\n"
        "def run(effects):\n"
        "    return Plant(disc_sets=3, effects=effects, effects_path='docs/examples/my_kinds').simulate_closed_loop(\n"
        "        amplitude_deg=20.0, freq_hz=2.0, cycles=2)\n"
        "base, sat = run({}), run({'aug_saturating_crank_load': {'c': 30.0, 'k': 5.0e5}})\n"
        "assert {f'aug_{k}_crank_load' for k in ('prop', 'beyond', 'saturating', 'cubic', 'knee')} <= set(balance_blocks())\n"
        "assert 'aug_const_crank_load' not in balance_blocks()\n"
        "assert get_effect('aug_saturating_crank_load').balance_place.quantity == 'p_load'\n"
        "print(float(np.max(np.abs(sat.theta_deg - base.theta_deg))))\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-1500:]
    # deg: a torque of 30 N m that follows the load pressure's sign moves the run
    assert float(r.stdout.strip().splitlines()[-1]) > 0.02


def test_a_term_of_the_piston_position_at_its_force_is_a_spring_on_the_crank():
    """A balance's other local quantities are the model's own (issue 43, places from the structure): a term
    proportional to the piston position x = r sin(theta) in the piston's force balance is, at the crank, a torque
    c r^2 sin(theta) cos(theta) / S -- within 1.5 % of a torsion spring k = -c r^2 / S over +-10 deg (the library's
    hyp_crank_spring, a law written independently); and a term of the load pressure at the piston's force is the
    load pressure's own force scaled (c / S = -A: the piston's area cancelled, the crank stalls at its start)."""
    place = get_effect("aug_prop_piston_position").balance_place
    assert (place.place, place.quantity) == ("piston_force", "x")
    c = -4000.0  # N at one span: a spring of 160 N/mm at the piston
    r = 0.05
    k = -c * r ** 2 / place.q_span
    run = lambda eff: Plant(disc_sets=3, effects=eff).simulate_closed_loop(amplitude_deg=10.0, freq_hz=2.0, cycles=3)
    spring, term, base = (run({"hyp_crank_spring": {"k": k, "T_0": 0.0}}), run({"aug_prop_piston_position": {"c": c}}),
                          run({}))
    d_spring = np.max(np.abs(spring.p_a_bar - base.p_a_bar))
    assert d_spring > 1.0  # bar: the spring loads the run
    assert np.max(np.abs(term.p_a_bar - spring.p_a_bar)) < 0.03 * d_spring
    assert {"piston_load_pressure", "crank_angle", "chamber_a_load_pressure", "chamber_b_velocity"} <= {
        p.short for p in balance_blocks.BALANCE_PLACES}


@pytest.mark.parametrize("stem,params,law", [
    ("const", {"c": 3.0}, lambda w: 3.0 + 0.0 * w),
    ("prop", {"c": 3.0}, lambda w: 3.0 * w / 10.0),
    ("beyond", {"c": 3.0, "k": 4.0}, lambda w: 3.0 * np.sign(w) * np.maximum(np.abs(w) - 4.0, 0.0) / 10.0),
    ("saturating", {"c": 3.0, "k": 4.0}, lambda w: 3.0 * np.where(np.abs(w) < 4.0, w / 4.0, np.sign(w))),
    ("cubic", {"c": 3.0}, lambda w: 3.0 * (w / 10.0) ** 3),
    ("knee", {"c": 3.0, "d": -6.0, "k": 4.0},
     lambda w: (3.0 * w - 6.0 * np.sign(w) * np.maximum(np.abs(w) - 4.0, 0.0)) / 10.0),
])
def test_a_kinds_term_is_its_law_written_out(stem, params, law):
    """term() at the crank rate (S = 10 rad/s), the law written out by cases; the valve's opening as no-load
    flow meters either way (abs)."""
    w = np.linspace(-12.0, 12.0, 97)
    name = "aug_const_piston_velocity" if stem == "const" else f"aug_{stem}_crank_rate"
    scale = 1.0 if stem == "const" else 10.0 / get_effect(name).balance_place.q_span
    assert get_effect(name).term(w * scale, params) == pytest.approx(law(w), abs=1e-12)
    q = np.linspace(-4.0e-4, 4.0e-4, 9)
    assert get_effect("aug_prop_supply").term(q, {"c": 2.0}) == pytest.approx(2.0 * np.abs(q) / (25.0 / 60000.0))


@pytest.mark.parametrize("place", [p.short for p in balance_blocks.BALANCE_PLACES])
def test_each_kind_finds_its_own_numbers_from_its_own_term(place):
    """nearest() of a kind's own term over the quantity's values returns its numbers (the sizes exactly, the
    break to a part in a thousand), at every place, a break well inside what the values reach."""
    p = [bp for bp in balance_blocks.BALANCE_PLACES if bp.short == place][0]
    q = np.linspace(-1.2 * p.q_span, 1.2 * p.q_span, 301) if p.centred else np.linspace(0.0, 1.2 * p.q_span, 301)
    for kind in balance_blocks.BALANCE_KINDS:
        if not kind.fits(p):
            continue
        cls = get_effect(f"aug_{kind.stem}_{place}")
        truth = {"c": 0.3 * p.out_span, "d": -0.5 * p.out_span, "k": 0.37 * p.q_span}
        truth = {n.name: truth[n.name] for n in cls.kind_params(p)}
        got = cls.nearest(q, cls.term(q, truth))
        assert got == pytest.approx(truth, rel=1e-3), (cls.__name__, got)


def test_a_simpler_kind_nested_in_a_piecewise_linear_term_is_found_in_it():
    """The piecewise-linear term holds three kinds: with its slope within nil, the term beyond the threshold
    (the same break, the slope beyond); with the slopes cancelling beyond, the saturating term (its level
    c k / S); with no change of slope, the proportional term.  A kind that cannot hold it gets its least-squares
    best (a cubic below the knee's largest value)."""
    w = np.linspace(-12.0, 12.0, 241)
    knee = get_effect("aug_knee_crank_rate")
    cases = [("beyond", {"c": 0.0, "d": -25.0, "k": 5.8}, {"c": -25.0, "k": 5.8}),
             ("saturating", {"c": -20.0, "d": 20.0, "k": 3.0}, {"c": -20.0 * 3.0 / 10.0, "k": 3.0}),
             ("prop", {"c": -20.0, "d": 0.0, "k": 3.0}, {"c": -20.0})]
    for stem, numbers, nested in cases:
        got = get_effect(f"aug_{stem}_crank_rate").nearest(w, knee.term(w, numbers))
        assert got == pytest.approx(nested, rel=1e-3), (stem, got)
    t = knee.term(w, {"c": 0.0, "d": -25.0, "k": 5.8})
    cubic = get_effect("aug_cubic_crank_rate")
    c = cubic.nearest(w, t)["c"]
    assert np.sum((cubic.term(w, {"c": c}) - t) ** 2) <= min(
        np.sum((cubic.term(w, {"c": c * f}) - t) ** 2) for f in (0.9, 1.1))


def test_a_cubic_term_holds_the_largest_term_of_its_place_where_the_runs_reach_a_third_of_the_span():
    """The cubic's size is its term at the span S: (S / (S/3))^3 = 27 times a term reached at a third of it, so its
    bounds are 27 times the place's largest term (a return pressure rising 2.9 bar at 8.6 of 25 L/min needs 71 bar
    at S: drawn case d03); the other kinds' sizes keep the place's."""
    from ehas_env.physics.effects import get_effect

    for place in ("return", "piston_velocity", "chamber_a"):
        cubic, prop = get_effect(f"aug_cubic_{place}"), get_effect(f"aug_prop_{place}")
        span = cubic.balance_place.out_span
        assert cubic.param("c").bounds == pytest.approx((-27.0 * span, 27.0 * span))
        assert prop.param("c").bounds == pytest.approx((-span, span))
        third = cubic.balance_place.q_span / 3.0
        assert cubic.term([third], {"c": cubic.param("c").bounds[1]})[0] == pytest.approx(span)
