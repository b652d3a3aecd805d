"""Synthetic measurement campaigns with hidden effects (written by ``ehas simulate-campaign``).

The rig is simulated as a test engineer would run it: several closed-loop sine
runs with the rig's controller (:meth:`RigController.book`) across disc sets,
amplitudes and frequencies, plus a valve chirp on the flow bench, all logged
through a realistic measurement chain (:class:`~ehas_env.simulation.sensors.Sensors`:
noise and 16-bit ADC / 12-bit DAC quantization).  With ``--perturb`` the
baseline's uncertain numbers differ from the nominal model as on a real rig:
bulk modulus beta by up to +-5 % and valve gain K by up to +-1 %.

The sidecars carry only what a rig log would (kind, disc sets, supply,
reference, controller); the truth (effects, beta, K, seed) goes to
``truth.json`` beside them, which campaign readers ignore.

Examples
--------
>>> runs, truth = simulate_campaign({"viscous_friction": {"b": 2500}}, seed=3, duration=0.5,
...                                 plan=DEFAULT_PLAN[:1])
>>> [name for name, _, _ in runs], truth["effects"]
(['cl_3sets_20deg_1hz', 'valve_chirp'], {'viscous_friction': {'b': 2500.0}})
"""
from __future__ import annotations

import json
from dataclasses import dataclass

#: closed-loop runs of the default campaign: (disc sets, amplitude deg, frequency Hz).
#: Chosen to span the rig's envelope (book tables 1.9-1.15 run 10-30 deg at 1-3 Hz with
#: 2-5 sets): a slow run (friction and leakage dominate), a heavy one, a fast light one
#: (high flow demand: droop, viscous friction, piston mass, delay) and a heavy
#: small-amplitude one (low hydraulic frequency, reversals at low speed).
DEFAULT_PLAN = ((3, 20.0, 1.0), (5, 30.0, 2.0), (1, 35.0, 3.0), (7, 10.0, 3.0))
DURATION = 3.0  # s per run
CHIRP = (0.5, 30.0, 8.0)  # valve chirp: start Hz, end Hz, amplitude mA (logarithmic sweep)
VALVE_SUPPLY_BAR = 70.0  # rated valve test (docs/rig.md)
BETA_PERTURB = 0.05  # relative, +-: the reference model's beta is an estimate
K_PERTURB = 0.01  # relative, +-: the identified K's fit uncertainty


@dataclass(frozen=True)
class RunPlan:
    """One closed-loop run of a plan: disc sets, sine amplitude (deg), frequency (Hz), mean angle (deg)."""

    disc_sets: int
    amplitude_deg: float
    freq_hz: float
    offset_deg: float = 0.0

    @property
    def name(self) -> str:
        sets = "1set" if self.disc_sets == 1 else f"{self.disc_sets}sets"
        off = f"_off{self.offset_deg:g}deg".replace("-", "m") if self.offset_deg else ""
        return f"cl_{sets}_{self.amplitude_deg:g}deg_{self.freq_hz:g}hz{off}".replace(".", "p")


def chirp_current(n: int, dt: float, f0: float = CHIRP[0], f1: float = CHIRP[1], amp: float = CHIRP[2]):
    """Logarithmic chirp from f0 to f1 Hz over n samples, amplitude ``amp`` mA."""
    import numpy as np

    t = np.arange(n) * dt
    T = n * dt
    k = np.log(f1 / f0) / T
    phase = 2 * np.pi * f0 * (np.exp(k * t) - 1.0) / k
    return amp * np.sin(phase)


def simulate_campaign(effects=None, *, seed: int = 0, perturb: bool = False, duration: float = DURATION,
                      plan=DEFAULT_PLAN, sensors=None, valve: bool = True, model=None):
    """Simulate a campaign in memory.

    Parameters
    ----------
    effects : dict or str
        Hidden effects, ``{"coulomb_friction": {"Fc": 300}}`` or ``"coulomb_friction:Fc=300"``.
    seed : int
        Seeds the sensor noise and the perturbations (same seed -> same campaign).
    perturb : bool
        Perturb beta (+-5 %) and K (+-1 %) at random.
    duration : float
        Length of each run, s.
    plan : sequence of (disc_sets, amplitude_deg, freq_hz[, offset_deg])
        The closed-loop runs; ``offset_deg`` (default 0) is the sine's mean angle,
        |offset| + amplitude below the stroke end (44.43 deg).
    sensors : Sensors, optional
        Measurement chain (default: :class:`Sensors` defaults, noisy and quantized).
    valve : bool
        Add the valve chirp run.
    model : PlantModel or str, optional
        The rig (a model file, docs/model-file.md; default the book's): its
        geometry, valve and effects, with ``effects`` hidden on top; the runs
        use the book's controller carried over to it (``PlantModel.controller``).

    Returns
    -------
    runs : list of (name, columns, meta)
        Ready for :func:`ehas_env.measurement.campaign.write_campaign`.
    truth : dict
        effects, beta (Pa), K (LPM/mA), seed, perturb.
    """
    import numpy as np

    from ehas_env.physics.effects import resolve_effects
    from ehas_env.simulation.plant import Plant, RigController
    from ehas_env.physics.rig import BULK_MODULUS, VALVE_K, RigParams
    from ehas_env.simulation.reference import SineReference
    from ehas_env.simulation.sensors import Sensors

    from ehas_env.simulation.model_file import as_model

    model = as_model(model)
    base = model.rig if model is not None else RigParams()
    effects = resolve_effects(effects)
    rng = np.random.default_rng(seed)
    beta = base.beta * (1.0 + (rng.uniform(-BETA_PERTURB, BETA_PERTURB) if perturb else 0.0))
    K = base.K * (1.0 + (rng.uniform(-K_PERTURB, K_PERTURB) if perturb else 0.0))
    sensors = Sensors() if sensors is None else sensors
    seeds = rng.integers(0, 2**31 - 1, size=len(plan) + 1)
    ctrl = model.controller() if model is not None else RigController.book()
    runs = []
    for row, s in zip(plan, seeds):
        p = RunPlan(*(int(row[0]), *(float(v) for v in row[1:])))
        plant = Plant(disc_sets=p.disc_sets, effects=effects, rig=base.replace(beta=beta, K=K), sensors=sensors,
                      seed=int(s), model=model)
        ref = SineReference(p.amplitude_deg, p.freq_hz, offset_deg=p.offset_deg)
        res = plant.simulate_closed_loop(ctrl, reference=ref, duration=duration)
        meta = {"kind": "closed_loop", "disc_sets": p.disc_sets, "supply_bar": res.meta["supply_bar"],
                "reference": res.meta["reference"], "controller": res.meta["controller"],
                "notes": f"synthetic run (ehas simulate-campaign, seed {seed})"}
        runs.append((p.name, res.columns(logged=True), meta))
    if valve:
        plant = Plant(effects=effects, rig=base.replace(beta=beta, K=K), sensors=sensors, seed=int(seeds[-1]),
                      model=model)
        n = int(round(duration / plant.dt))
        cmd = chirp_current(n, plant.dt)
        # the DAC quantizes the chirp as it quantizes the controller's output
        lsb = sensors.current_lsb
        if lsb > 0:
            cmd = lsb * np.floor(cmd / lsb + 0.5)
        vr = plant.simulate_valve_test(cmd, supply_bar=VALVE_SUPPLY_BAR)
        cols = {"t": vr.t, "current_mA": vr.current_mA, "flow_lpm": vr.logged.get("flow_lpm", vr.flow_lpm)}
        meta = {"kind": "valve_open_loop", "supply_bar": VALVE_SUPPLY_BAR,
                "notes": f"valve chirp {CHIRP[0]:g}-{CHIRP[1]:g} Hz, {CHIRP[2]:g} mA, flow bench (seed {seed})"}
        runs.append(("valve_chirp", cols, meta))
    truth = {"effects": effects, "beta": beta, "K": K, "seed": seed, "perturb": perturb,
             "sensors": sensors.to_dict(), "duration_s": duration,
             "plan": [list(p) for p in plan]}
    if model is not None:
        truth["model"] = model.to_dict()
    return runs, truth


def write_simulated_campaign(out, effects=None, *, seed: int = 0, perturb: bool = False, command: str | None = None,
                             overwrite: bool = False, fmt: str = "csv", **kwargs):
    """Simulate and write a campaign folder with ``truth.json`` and a README.

    ``fmt`` is the runs' data file format (``csv``, ``mat``, ``tdms``, ``hdf5``,
    ``parquet``; :func:`~ehas_env.measurement.campaign.write_campaign`); the
    other arguments are :func:`simulate_campaign`'s.
    """
    from ehas_env.measurement.campaign import write_campaign
    from ehas_env.measurement.formats import by_name

    suffix = by_name(fmt).suffixes[0]
    runs, truth = simulate_campaign(effects, seed=seed, perturb=perturb, **kwargs)
    command = command or _command(truth, fmt)
    truth["command"] = command
    readme = (
        "# Synthetic measurement campaign\n\n"
        f"Regenerate with:\n\n    {command}\n\n"
        f"Each `RUN{suffix}` + `RUN.json` pair is one run in the measurement format (docs/measurement-format.md).\n"
        "`truth.json` records what was simulated (hidden effects, beta, K, seed); campaign readers\n"
        "ignore it, so `ehas diagnose` works blind.\n"
    )
    extra = {"truth.json": json.dumps(truth, indent=2) + "\n", "README.md": readme}
    return write_campaign(out, runs, extra, overwrite=overwrite, fmt=fmt), truth


def _command(truth, fmt: str = "csv") -> str:
    eff = ",".join(f"{n}:" + ",".join(f"{k}={v:g}" for k, v in p.items()) for n, p in truth["effects"].items())
    parts = ["ehas simulate-campaign"]
    if eff:
        parts.append(f"--effects {eff}")
    parts.append(f"--seed {truth['seed']}")
    if truth["perturb"]:
        parts.append("--perturb")
    if fmt != "csv":
        parts.append(f"--format {fmt}")
    return " ".join(parts) + " --out DIR"


