"""Plants built to break the learning controllers (issue 45), for the guard's tests and the guard long test.

Shares no code with the guard (``ehas_controllers.learning``): each plant is the package's ``Plant`` with
something a real rig has and the design model has not, judged by the long-test metric on the true angle:

* ``slip``: the disc stack sits on the shaft through a coupling that slips at high torque
  (``breaking_effects/slip_coupling.py``, an effect file loaded by its path as a user's would be:
  the crank carries a 0.05 kg m^2 hub, the stack of 0.383 kg m^2 per disc set is behind a Dahl friction
  coupling of 5e4 N m/rad slipping at 350 N m);
* ``jitter``: the controller's sample instants wander by up to +-0.3 ms (uniform, independent per sample)
  around its nominal ones: it believes it samples at k dt, it reads the angle at k dt + d_k and its
  command is applied from then to the next wandering instant (:func:`closed_loop_jitter`);
* ``sensors``: the package's sensor layer (LVDT noise 0.01 deg, 16-bit ADC, 12-bit DAC) with a noise seed;
* ``gain_half`` / ``gain_double``: the valve's flow gain 0.5 x / 2 x the design model's (``valve_dynamics`` K);
* ``delay``: a transport delay of 4 ms between the controller's output and the valve (``transport_delay``).

Run as a module it writes the guard long test (``results/long_test_guard/``; its README holds the command):
``python -m tests.breaking_plants --out results/long_test_guard``.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from ehas_env.physics import layout as K
from ehas_env.physics.rig import BAR, INERTIA_PER_SET
from ehas_env.simulation.long_test import long_test_metrics
from ehas_env.simulation.plant import Plant
from ehas_env.simulation.reference import SineReference
from ehas_env.simulation.sensors import Sensors

HERE = Path(__file__).resolve().parent
EFFECTS_DIR = HERE / "breaking_effects"
JITTER_S = 0.3e-3
HUB_INERTIA = 0.05  # kg m^2, the crank and shaft in front of the slipping coupling
VALVE_K = 1.2723  # LPM/mA, the book's valve flow gain (the design model's)
DELAY_S = 0.004
#: plant name -> what it is, in words
PLANTS = {
    "book": "the book's model (the design model)",
    "slip": "disc stack behind a coupling slipping at 350 N m (hub 0.05 kg m^2, Dahl coupling 5e4 N m/rad)",
    "jitter": "sample instants wandering by +-0.3 ms (uniform, independent per sample)",
    "sensors": "the sensor layer on (LVDT noise 0.01 deg, 16-bit ADC, 12-bit DAC), one noise seed per run",
    "gain_half": "valve flow gain 0.5 x the design model's (K = 0.636 LPM/mA)",
    "gain_double": "valve flow gain 2 x the design model's (K = 2.545 LPM/mA)",
    "delay": "transport delay of 4 ms between the controller's output and the valve",
}


def plant_kwargs(name: str, disc_sets: int, seed: int = 0) -> dict:
    """``Plant`` arguments of a breaking plant (``jitter``: the book's plant; its loop is the breaking part)."""
    if name in ("book", "jitter"):
        return {"seed": seed}
    if name == "slip":
        return {"inertia": HUB_INERTIA, "effects": {"slip_coupling": {"I_discs": disc_sets * INERTIA_PER_SET}},
                "effects_path": str(EFFECTS_DIR / "slip_coupling.py"), "seed": seed}
    if name == "sensors":
        return {"sensors": Sensors(), "seed": seed}
    if name in ("gain_half", "gain_double"):
        return {"effects": {"valve_dynamics": {"K": VALVE_K * (0.5 if name == "gain_half" else 2.0)}}, "seed": seed}
    if name == "delay":
        return {"effects": {"transport_delay": {"tau": DELAY_S}}, "seed": seed}
    raise ValueError(f"unknown breaking plant {name!r}; one of {', '.join(PLANTS)}")


def closed_loop_jitter(controller, plant: Plant, amplitude_deg: float, freq_hz: float, duration: float,
                       jitter_s: float = JITTER_S, seed: int = 0):
    """A closed loop whose sample instants wander: sample k is taken at k dt + d_k, d_k ~ U(-jitter, +jitter).

    The controller is told ``t = k dt`` and its own reference at k dt; it reads the angle at the true
    instant; its command holds until the next true instant (the plant integrates each true period with the
    model's RK4, ``advance`` with that period's length).  Returned: the true instants (s), the reference at
    them (deg, as the rig's motion is judged) and the true angle (deg).

    Parameters
    ----------
    controller : object
        ``reset()`` and ``act(measurement) -> mA``.
    plant : Plant
        The plant (its sensors must be ideal here).
    amplitude_deg, freq_hz : float
        The reference.
    duration : float
        Seconds.
    jitter_s : float
        Largest wander of a sample instant, s.
    seed : int
        Seed of the wander.

    Returns
    -------
    tuple of ndarray
        ``(t_true, theta_ref_deg, theta_deg)``.
    """
    M, P, dt = plant.model, plant.param_vector, plant.dt
    n = int(round(duration / dt))
    d = np.random.default_rng(seed).uniform(-jitter_s, jitter_s, n + 1)
    d[0] = 0.0
    ref = SineReference(amplitude_deg, freq_hz)
    rv = ref.kernel_vector()
    s = plant.initial_state(0.0)
    hist = np.zeros(K.history_length(0.05, dt))
    out = np.zeros(K.N_OUT)
    k1, k2, k3, k4, tmp = (np.empty_like(s) for _ in range(5))
    t_true, th_true, r_true = np.zeros(n), np.zeros(n), np.zeros(n)
    controller.reset()
    for k in range(n):
        M.measure(s, P, out)
        tk = k * dt + d[k]
        th = math.degrees(out[K.O_THETA])
        t_true[k], th_true[k] = tk, th
        r_true[k] = M.reference_point(rv, tk)[0]
        r, rd, rdd, rddd = M.reference_point(rv, k * dt)
        u = float(controller.act({"t": k * dt, "theta_deg": th, "theta_ref_deg": r, "theta_ref_dot": rd,
                                  "theta_ref_ddot": rdd, "theta_ref_dddot": rddd, "p_a_bar": s[4] / BAR,
                                  "p_b_bar": s[5] / BAR, "p_s_bar": s[6] / BAR, "amplitude_deg": amplitude_deg,
                                  "freq_hz": freq_hz}))
        hist[k % hist.shape[0]] = min(max(u, -20.0), 20.0)
        M.advance(s, P, hist, k, dt + d[k + 1] - d[k], plant.substeps, 0.0, k1, k2, k3, k4, tmp)
    return t_true, r_true, th_true


def run(controller, plant: str, disc_sets: int, amplitude_deg: float, freq_hz: float, cycles: int = 30,
        seed: int = 0) -> dict:
    """One long-test run of ``controller`` on a breaking plant: the long-test figures on the true angle.

    Returns
    -------
    dict
        :func:`~ehas_env.simulation.long_test.long_test_metrics`, plus ``controller`` (the copy that ran,
        for its guard log).
    """
    sub = controller.for_plant(disc_sets) if hasattr(controller, "for_plant") else controller
    p = Plant(disc_sets=disc_sets, **plant_kwargs(plant, disc_sets, seed))
    duration = cycles / freq_hz + 2 * p.dt
    if plant == "jitter":
        t, ref, th = closed_loop_jitter(sub, p, amplitude_deg, freq_hz, duration, seed=seed)
    else:
        res = p.simulate_closed_loop(sub, amplitude_deg=amplitude_deg, freq_hz=freq_hz, duration=duration)
        t, ref, th = res.t, res.theta_ref_deg, res.theta_deg
    m = long_test_metrics(t, ref, th, amplitude_deg, freq_hz)
    m["controller"] = sub
    return m


def plants(names, seeds: int) -> list[dict]:
    """The :func:`ehas_controllers.long_test.guard_long_test` plants named (``sensors`` over ``seeds`` seeds)."""
    from ehas_controllers.long_test import plant_runner

    def runner(name):
        if name == "jitter":
            def run_jitter(controller, cond, cycles, seed):
                from ehas_controllers.long_test import guard_fields

                m = run(controller, "jitter", cond.disc_sets, cond.amplitude_deg, cond.freq_hz, cycles, seed)
                return {**m, **guard_fields(m["controller"])}
            return run_jitter
        return plant_runner(lambda n, seed: plant_kwargs(name, n, seed))

    return [{"name": n, "what": PLANTS[n], "run": runner(n), "seeds": list(range(seeds)) if n == "sensors" else [0]}
            for n in names]


def main(argv=None) -> int:
    """``python -m tests.breaking_plants --out DIR``: the guard long test (``--help``)."""
    import shlex
    import sys

    from ehas_controllers.base import load_controller
    from ehas_controllers.batch_sim import grid
    from ehas_controllers.long_test import guard_long_test

    ap = argparse.ArgumentParser(prog="python -m tests.breaking_plants", description=__doc__.split("\n")[0])
    ap.add_argument("controllers", nargs="*", default=["results/long_test_guard/ilc.json",
                                                       "results/long_test_guard/harmonic.json"])
    ap.add_argument("--out", required=True)
    ap.add_argument("--plants", default=",".join(PLANTS), help="comma-separated, of " + ", ".join(PLANTS))
    ap.add_argument("--seeds", type=int, default=5, help="noise seeds of the sensors plant (default 5)")
    ap.add_argument("--cycles", type=int, default=30)
    ap.add_argument("--disc-sets", default="1,2,3,4,5,6,7")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    names = [n for n in args.plants.split(",") if n]
    for n in names:
        if n not in PLANTS:
            raise SystemExit(f"--plants: unknown plant {n!r}; one of {', '.join(PLANTS)}")
    ctrls = [load_controller(p) for p in args.controllers]
    conds = grid(tuple(int(x) for x in args.disc_sets.split(",")))
    command = "python -m tests.breaking_plants " + " ".join(shlex.quote(a) for a in (argv if argv is not None
                                                                                      else sys.argv[1:]))
    res = guard_long_test(ctrls, plants(names, args.seeds), args.out, conditions=conds, cycles=args.cycles,
                          command=command.strip(), progress=not args.no_progress, save_learned="book")
    for s in res["summary"]:
        print(f"{s['controller']:<38} {s['plant']:<12} median seed {s['median_seed_mean_pct']:.4f} %  worst seed "
              f"{s['worst_seed_mean_pct']:.4f} %  base {s['base_mean_pct']:.4f} %  worse than base "
              f"{s['worse_than_base']}/{s['runs']}  gated {s['gated_runs']}  dropped {s['dropped_runs']}  guard "
              f"{s['guarded_runs']}/{s['fallbacks_to_base']}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
