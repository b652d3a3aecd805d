"""Characteristic curves of the servo valve and the position loop (book chapters 2-5).

* :func:`flow_vs_current` - no-load flow against current at several supply
  pressures (a higher supply needs less current for the same flow);
* :func:`lap_flow` / :func:`lap_pressure` - flow gain and blocked-port
  pressure against spool stroke for under-, critically and over-lapped spools;
* :func:`valve_tf` - the valve's transfer function (grey or white box);
* :func:`position_loop` - the rig's position loop linearised at mid-stroke
  (analytically, as state-space matrices for python-control), its loop
  transfer function for a :class:`~ehas_env.simulation.plant.RigController`, and its gain
  and phase margins.

Spool geometry comes from the white-box valve (:mod:`ehas_env.physics.white_box_valve`):
port width ``w`` from the book's K3.  Assumed here (not in the book): lap of the
under- and over-lapped spools +-0.05 mm (6 % of the 0.79 mm rated stroke),
radial clearance 3 um and oil viscosity 0.0128 Pa s (MIL-H-5606, 15 cSt near
40 degC) for the leakage past closed lands.

Examples
--------
>>> round(flow_vs_current(20.0, 220.0), 1)      # K 20 mA sqrt(220 / 70)
45.1
>>> loop = position_loop()          # 3 disc sets, the book's gains
>>> round(loop["crossover_hz"], 1), round(loop["phase_margin_deg"]), round(loop["gain_margin_db"], 1)
(9.3, 39, 5.7)
"""
from __future__ import annotations

import math

import numpy as np

from ehas_env.physics.rig import BAR, LPM

LAP = 0.05e-3  # m, under-/over-lap of the illustrated spools (assumed)
CLEARANCE = 3.0e-6  # m, radial clearance of the spool (assumed, Merritt: 2.5-5 um)
VISCOSITY = 0.0128  # Pa s, MIL-H-5606 at ~40 degC (15 cSt x 850 kg/m^3, assumed)


# ---------------------------------------------------------------------------
# valve statics
# ---------------------------------------------------------------------------

def flow_vs_current(current_mA, supply_bar, *, K: float = 1.2723, i_max: float = 20.0):
    """No-load flow (LPM) of the grey-box valve: K clip(i) sqrt(Ps / 70 bar), Merritt's form with P_L = 0.

    Examples
    --------
    >>> round(flow_vs_current(20.0, 70.0), 3)   # the rated test
    25.446
    """
    i = np.clip(np.asarray(current_mA, dtype=float), -i_max, i_max)
    out = K * i * math.sqrt(supply_bar / 70.0)
    return float(out) if np.ndim(out) == 0 else out


def current_for_flow(flow_lpm: float, supply_bar: float, *, K: float = 1.2723) -> float:
    """Current (mA) that gives ``flow_lpm`` at no load and ``supply_bar``: a higher supply needs less."""
    return flow_lpm / (K * math.sqrt(supply_bar / 70.0))


def _opening(x, lap):
    """Openings of the four lands (S->A, A->T, S->B, B->T) for stroke x and lap (> 0 underlap, < 0 overlap)."""
    return lap + x, lap - x, lap - x, lap + x


def lap_flow(x, lap: float, supply_bar: float = 220.0, valve=None):
    """No-load load flow (LPM) against spool stroke x (m) for a lap (m; > 0 under-, < 0 over-lapped).

    At P_L = 0 both chambers sit at Ps/2; each metering land passes
    Cd w max(opening, 0) sqrt(Ps / rho), so
    Q_L = K3 (max(U + x, 0) - max(U - x, 0)) sqrt(Ps / dp_n): twice the
    critically lapped gain inside an underlap, none inside an overlap.

    Examples
    --------
    >>> q_c = lap_flow(0.02e-3, 0.0, 70.0); q_u = lap_flow(0.02e-3, 0.05e-3, 70.0)
    >>> round(float(q_u / q_c), 6), float(lap_flow(0.02e-3, -0.05e-3, 70.0))
    (2.0, 0.0)
    """
    from ehas_env.physics.white_box_valve import WhiteBoxValve

    v = valve or WhiteBoxValve()
    x = np.asarray(x, dtype=float)
    o1, o4, _, _ = _opening(x, lap)
    q = v.K3 * (np.maximum(o1, 0.0) - np.maximum(o4, 0.0)) * math.sqrt(supply_bar * BAR / v.rated_drop)
    return q / LPM


def _land_flow(opening, dp, w, cd, rho):
    """Flow through one land: turbulent orifice when open, laminar leakage through the clearance when closed."""
    dp = max(dp, 0.0)
    if opening > 0.0:
        q = cd * w * opening * math.sqrt(2.0 * dp / rho)
    else:
        q = 0.0
    # the clearance leaks along the covered length (at least one clearance long)
    length = max(-opening, 0.0) + CLEARANCE
    return q + w * CLEARANCE**3 * dp / (12.0 * VISCOSITY * length)


def lap_pressure(x, lap: float, supply_bar: float = 220.0, valve=None):
    """Blocked-port load pressure P_L = P_A - P_B (bar) against spool stroke x (m).

    Each chamber's pressure balances the flow in from supply with the flow out
    to tank (no load flow); the pressure gain is the slope at null.
    """
    from scipy.optimize import brentq

    from ehas_env.physics.white_box_valve import WhiteBoxValve

    v = valve or WhiteBoxValve()
    ps = supply_bar * BAR

    def chamber(o_in, o_out):
        f = lambda p: _land_flow(o_in, ps - p, v.w, v.Cd, v.rho) - _land_flow(o_out, p, v.w, v.Cd, v.rho)
        return brentq(f, 0.0, ps, xtol=1e-6, rtol=1e-12)

    xs = np.atleast_1d(np.asarray(x, dtype=float))
    out = np.empty(xs.size)
    for k, xx in enumerate(xs):
        o1, o4, o2, o3 = _opening(xx, lap)
        out[k] = (chamber(o1, o4) - chamber(o2, o3)) / BAR
    return float(out[0]) if np.ndim(x) == 0 else out


def pressure_gain(lap: float, supply_bar: float = 220.0, valve=None, dx: float = 0.05e-6) -> float:
    """Blocked-port pressure gain at null, bar per um of spool stroke."""
    return (lap_pressure(dx, lap, supply_bar, valve) - lap_pressure(-dx, lap, supply_bar, valve)) / (2 * dx * 1e6)


# ---------------------------------------------------------------------------
# valve and loop dynamics
# ---------------------------------------------------------------------------

def valve_tf(valve: str = "grey_box", supply_bar: float = 220.0, slots: dict | None = None):
    """q_c / i (LPM/mA at the rated drop) of the grey box (``slots`` K, wn, zeta) or the white box."""
    import control

    if valve == "white_box":
        from ehas_env.physics.white_box_valve import WhiteBoxValve

        return WhiteBoxValve().transfer_function(supply_bar)
    if valve != "grey_box":
        raise ValueError(f"valve must be 'grey_box' or 'white_box', got {valve!r}")
    if slots is None:
        from ehas_env.physics.rig import VALVE_K, VALVE_WN, VALVE_ZETA

        K, wn, z = VALVE_K, VALVE_WN, VALVE_ZETA
    else:
        K, wn, z = slots["K"] / LPM, slots["wn"], slots["zeta"]
    return control.tf([K * wn * wn], [1.0, 2.0 * z * wn, wn * wn])


def linear_plant(plant=None, valve: str | None = None):
    """State-space model i (mA) -> (theta deg, P_A - P_B bar) at mid-stroke, at rest.

    The project's one linearisation (``ehas_env.simulation.linear_model.LinearPlant``,
    the compiled model differentiated numerically): every smooth effect of the
    plant is in it; Coulomb/Stribeck friction, backlash and a deadband have no
    small-signal term at rest and are left out (see ``ehas_env.physics.linearise``).
    ``valve`` swaps the plant's valve model.
    """
    from ehas_env.simulation.linear_model import LinearPlant
    from ehas_env.simulation.plant import Plant

    plant = plant if plant is not None else Plant()
    if valve is not None and valve != plant.valve:
        plant = Plant(disc_sets=plant.rig.disc_sets, effects=plant.effects or None, rig=plant.rig, valve=valve,
                      dt=plant.dt, substeps=plant.substeps)
    return LinearPlant(plant).state_space()


def position_loop(plant=None, controller=None, valve: str | None = None, pade_order: int = 3) -> dict:
    """Loop transfer function at the valve current, its margins and crossovers.

    L(s) = [C(s) G_theta(s) + Kdp H(s) G_dP(s)] e^{-s (dt/2 + tau)}, where
    C = Kp + Ki/s (mA/deg; the feed-forward terms are outside the loop), H the
    pressure feedback's high-pass, and the delay holds the zero-order hold's
    half sample and any transport delay (Pade approximation).

    Returns a dict with ``L`` (control.TransferFunction), ``gain_margin_db``,
    ``phase_margin_deg``, ``crossover_hz`` (first |L| = 1), ``phase_crossover_hz``
    (first phase -180 deg), ``hydraulic_hz`` (the linear plant's resonance),
    ``closed_loop_stable`` (all poles of L / (1 + L) in the left half-plane).
    """
    import control

    from ehas_env.simulation.plant import Plant, RigController

    plant = plant if plant is not None else Plant()
    ctrl = controller if controller is not None else RigController.book()
    G = linear_plant(plant, valve)
    g_th = control.ss2tf(G[0, 0])
    g_dp = control.ss2tf(G[1, 0])
    s = control.tf("s")
    C = ctrl.Kp + ctrl.Ki / s
    L = C * g_th
    if ctrl.Kdp:
        H = s / (s + ctrl.dp_hp) if ctrl.dp_hp > 0 else control.tf([1.0], [1.0])
        L = L + ctrl.Kdp * H * g_dp
    delay = 0.5 / ctrl.rate_hz + plant.slots()["tau"]
    if delay > 0:
        num, den = control.pade(delay, pade_order)
        L = L * control.tf(num, den)
    L = control.minreal(L, verbose=False)
    # the margins of the first (lowest-frequency) crossings: the linearisation at rest has an
    # undamped hydraulic resonance (K_c = 0 at null) whose peak crosses 0 dB again; whether the
    # loop is stable is decided by the closed-loop poles
    gms, pms, _, w_pcs, w_gcs, _ = control.stability_margins(L, returnall=True)
    gm, w_pc, pm, w_gc = math.inf, math.nan, math.nan, math.nan
    if len(w_pcs):
        k = int(np.argmin(w_pcs))
        gm, w_pc = float(gms[k]), float(w_pcs[k])
    if len(w_gcs):
        k = int(np.argmin(w_gcs))
        pm, w_gc = float(pms[k]), float(w_gcs[k])
    cl_poles = control.feedback(L, 1).poles()
    poles = np.linalg.eigvals(G.A)
    osc = [p for p in poles if p.imag > 1e-6]
    w_hyd = min((abs(p) for p in osc), key=lambda w: abs(w - plant.rig.hydraulic_natural_frequency()), default=float("nan"))
    return {
        "L": L,
        "gain_margin_db": float(20 * math.log10(gm)) if np.isfinite(gm) and gm > 0 else float("inf"),
        "gain_margin": float(gm),
        "phase_margin_deg": float(pm),
        "crossover_hz": float(w_gc / (2 * math.pi)) if np.isfinite(w_gc) else float("nan"),
        "phase_crossover_hz": float(w_pc / (2 * math.pi)) if np.isfinite(w_pc) else float("nan"),
        "hydraulic_hz": float(w_hyd / (2 * math.pi)),
        "closed_loop_stable": bool(np.all(np.real(cl_poles) < 0)),
        "delay_s": delay,
    }


# ---------------------------------------------------------------------------
# the whole set, as figures and a summary
# ---------------------------------------------------------------------------

def write_curves(out, *, plant=None, controller=None, supplies_bar=(70.0, 140.0, 220.0), valve: str = "grey_box",
                 command: str = "ehas curves") -> "Path":
    """Write the curves' PNGs and ``README.md`` (tables, the command) into ``out``; returns the README path."""
    from pathlib import Path

    from ehas_env.output.files import atomic_write_text
    from ehas_env.output.identification_plots import plot_bode, save
    from ehas_env.simulation.plant import Plant, RigController
    from ehas_env.output.plots import _pyplot
    from ehas_env.physics.white_box_valve import WhiteBoxValve

    from ehas_env.output.progress import status

    out = Path(out)
    status(f"1/5 flow against current at {', '.join(f'{p:g}' for p in supplies_bar)} bar", "curves")
    plant = plant if plant is not None else Plant()
    ctrl = controller if controller is not None else RigController.book()
    plt = _pyplot()
    wb = WhiteBoxValve()
    files = []

    # 1. flow vs current
    pm = getattr(plant, "plant_model", None)  # a model file's rig (docs/model-file.md): its valve rating
    rig_k, i_rated = plant.rig.K, plant.rig.i_max
    rated = rig_k * i_rated
    i = np.linspace(-i_rated, i_rated, 201)
    fig, ax = plt.subplots(figsize=(7, 5))
    need = []
    for k, ps in enumerate(supplies_bar):
        ax.plot(i, flow_vs_current(i, ps, K=rig_k, i_max=i_rated), color=f"C{k}", label=f"grey box, Ps = {ps:g} bar")
        ax.plot(i, [wb.steady_flow_lpm(x, ps) for x in i], "--", color=f"C{k}", lw=0.9,
                label=f"white box, Ps = {ps:g} bar")
        need.append((ps, current_for_flow(25.0 if pm is None else rated, ps, K=rig_k), wb.steady_flow_lpm(20.0, ps)))
    ax.axhline(rated if pm is not None else 25.0, color="k", lw=0.6, ls=":")
    ax.axhline(-rated if pm is not None else -25.0, color="k", lw=0.6, ls=":")
    ax.set_xlabel("current, mA")
    ax.set_ylabel("no-load flow, LPM")
    ax.set_title("flow against current (no load); dotted: rated 25 LPM" if pm is None else
                 f"{pm.label}: flow against current (no load); dotted: rated {rated:.3g} LPM", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    files.append(save(fig, out / "flow_vs_current.png"))

    # 2. flow and flow gain vs stroke for three laps
    status("2/5 flow and flow gain against spool stroke", "curves")
    x = np.linspace(-0.3e-3, 0.3e-3, 601)
    laps = (("underlapped", LAP), ("critically lapped", 0.0), ("overlapped", -LAP))
    fig, ax = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    for name, lap in laps:
        q = lap_flow(x, lap, 220.0, wb)
        ax[0].plot(x * 1e3, q, label=f"{name} ({lap * 1e3:+.2f} mm)")
        ax[1].plot(x * 1e3, np.gradient(q, x * 1e3), label=name)
    ax[0].set_ylabel("no-load flow Q_L, LPM (220 bar)")
    ax[1].set_ylabel("flow gain K_q, LPM/mm")
    ax[1].set_xlabel("spool stroke x_v, mm")
    ax[0].legend(fontsize=8)
    for a in ax:
        a.grid(alpha=0.3)
    ax[0].set_title("flow and flow gain against spool stroke", fontsize=10)
    files.append(save(fig, out / "flow_gain_vs_stroke.png"))
    kq = {name: float(np.gradient(lap_flow(np.array([-1e-6, 0.0, 1e-6]), lap, 220.0, wb), 1e-3)[1]) for name, lap in laps}

    # 3. pressure gain
    status("3/5 pressure gain", "curves")
    xp = np.linspace(-0.1e-3, 0.1e-3, 401)
    fig, ax = plt.subplots(figsize=(7, 5))
    kp = {}
    for name, lap in laps:
        ax.plot(xp * 1e3, lap_pressure(xp, lap, 220.0, wb), label=f"{name} ({lap * 1e3:+.2f} mm)")
        kp[name] = pressure_gain(lap, 220.0, wb)
    ax.set_xlabel("spool stroke x_v, mm")
    ax.set_ylabel("blocked-port load pressure P_L, bar (220 bar)")
    ax.set_title(f"pressure against stroke, ports blocked (radial clearance {CLEARANCE * 1e6:g} um)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    files.append(save(fig, out / "pressure_gain.png"))

    # 4. valve Bode
    status("4/5 valve Bode plot", "curves")
    files.append(plot_bode([("grey box (identified)", valve_tf("grey_box")),
                            ("white box, 70 bar", valve_tf("white_box", 70.0)),
                            ("white box, 220 bar", valve_tf("white_box", 220.0))],
                           out / "valve_bode.png", title="valve q_c / i, LPM/mA", f_range=(0.5, 2000.0)))

    # 5. position loop
    status("5/5 position loop (linearised) Bode plot and margins", "curves")
    loop = position_loop(plant, ctrl, valve)
    files.append(_plot_loop(loop, out / "position_loop_bode.png",
                            title=(f"{pm.label}: " if pm is not None else "")
                                  + f"position loop (linearised at mid-stroke, at rest), {plant.rig.disc_sets} disc sets, "
                                  f"{'book rig' if pm is None else 'model'}, valve {valve}\n"
                                  f"controller: Kp {ctrl.Kp:g} mA/deg, Ki {ctrl.Ki:g} mA/(deg s)"
                                  + (f", Kdp {ctrl.Kdp:g} mA/bar" if ctrl.Kdp else "")
                                  + f", ZOH half-sample delay; loop broken at the valve current"))
    sweep = []
    for n in range(1, 8):
        p = Plant(disc_sets=n, effects=plant.effects or None, **({"valve": valve} if valve != "grey_box" else {}),
                  **({"model": pm} if pm is not None else {}))
        lp = position_loop(p, ctrl, valve)
        sweep.append((n, lp))

    md = ["# Valve characteristic curves and the position loop", "", f"Regenerate: `{command}`", "",
          f"Plant: {plant!r}, valve {valve}; controller {ctrl.to_dict()}.", "",
          "## Flow against current (no load)", "",
          "| supply, bar | current for 25 LPM (grey box), mA | white box flow at 20 mA, LPM |", "|---|---|---|"]
    md += [f"| {ps:g} | {cur:.1f}{' (beyond 20 mA: not reachable)' if cur > 20 else ''} | {wq:.1f} |"
           for ps, cur, wq in need]
    md += ["", "A higher supply pressure needs less current for the same flow (Q = K i sqrt(Ps / 70 bar)).", "",
           "## Spool lap (220 bar, port width w = %.2f mm from K3)" % (wb.w * 1e3), "",
           "| spool | flow gain at null, LPM/mm | blocked-port pressure gain at null, bar/um |", "|---|---|---|"]
    md += [f"| {name} | {kq[name]:.0f} | {kp[name]:.1f} |" for name, _ in laps]
    md += ["", f"Laps +-{LAP * 1e3:g} mm, radial clearance {CLEARANCE * 1e6:g} um, viscosity {VISCOSITY:g} Pa s: "
           "assumed (see `ehas_env/identification/curves.py`). Underlap doubles the flow gain near null and lowers the pressure "
           "gain; overlap gives a dead zone in flow.", "",
           "## Position loop (linearised at mid-stroke; ZOH half-sample and transport delay as Pade)", "",
           "| disc sets | hydraulic resonance, Hz | gain crossover, Hz | phase margin, deg | gain margin, dB | "
           "phase crossover, Hz | closed loop |", "|---|---|---|---|---|---|---|"]
    md += [f"| {n}{' (this plant)' if n == plant.rig.disc_sets else ''} | {lp['hydraulic_hz']:.1f} | "
           f"{lp['crossover_hz']:.2f} | {lp['phase_margin_deg']:.1f} | {lp['gain_margin_db']:.1f} | "
           f"{lp['phase_crossover_hz']:.1f} | {'stable' if lp['closed_loop_stable'] else 'UNSTABLE'} |"
           for n, lp in sweep]
    md += ["", "Margins at the first crossings. Linearised at rest the lands have no pressure-flow coefficient "
           "(K_c = 0), so the hydraulic resonance is undamped and its peak crosses 0 dB again (visible in the "
           "Bode plot); the closed-loop poles decide stability. The phase crossover is set by the valve's lag "
           "with the two integrators (PI, and flow -> position); a heavier load brings the hydraulic resonance "
           "nearer, raises |L| there and so lowers the gain margin. "
           "Feed-forward gains (Kv, Ka, Kj) act outside the loop and do not change the margins. Coulomb "
           "friction, backlash, deadband and supply droop are not linear at rest and are left out of the "
           "linearisation.", "", "Files: " + ", ".join(f"`{f.name}`" for f in files), ""]
    return atomic_write_text(out / "README.md", "\n".join(md))


def _plot_loop(loop: dict, path, title: str):
    from ehas_env.output.identification_plots import save
    from ehas_env.output.plots import _pyplot

    plt = _pyplot()
    L = loop["L"]
    w = np.geomspace(2 * math.pi * 0.05, 2 * math.pi * 500, 2000)
    # evaluated just right of the imaginary axis: the undamped resonance at rest then drops the
    # phase by 180 deg, as any lightly damped resonance does, instead of an arbitrary +-180 step
    g = np.squeeze(L(1e-3 * w + 1j * w))
    fig, ax = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True)
    f = w / (2 * math.pi)
    ax[0].semilogx(f, 20 * np.log10(np.abs(g)), color="C0", label="loop L at the valve current")
    ax[0].axhline(0, color="k", lw=0.6)
    ax[1].semilogx(f, np.degrees(np.unwrap(np.angle(g))), color="C0")
    ax[1].axhline(-180, color="k", lw=0.6)
    if np.isfinite(loop["crossover_hz"]):
        for a in ax:
            a.axvline(loop["crossover_hz"], color="C2", lw=1.0, ls="--",
                      label=f"gain crossover {loop['crossover_hz']:.2f} Hz: phase margin {loop['phase_margin_deg']:.1f} deg"
                      if a is ax[0] else None)
        ax[1].annotate("", xy=(loop["crossover_hz"], -180 + loop["phase_margin_deg"]), xytext=(loop["crossover_hz"], -180),
                       arrowprops=dict(arrowstyle="<->", color="C2", lw=1.5))
    if np.isfinite(loop["phase_crossover_hz"]):
        for a in ax:
            a.axvline(loop["phase_crossover_hz"], color="C3", lw=1.0, ls="--",
                      label=f"phase crossover {loop['phase_crossover_hz']:.1f} Hz: gain margin {loop['gain_margin_db']:.1f} dB"
                      if a is ax[0] else None)
        ax[0].annotate("", xy=(loop["phase_crossover_hz"], -loop["gain_margin_db"]), xytext=(loop["phase_crossover_hz"], 0),
                       arrowprops=dict(arrowstyle="<->", color="C3", lw=1.5))
    if np.isfinite(loop.get("hydraulic_hz", math.nan)):
        for a in ax:
            a.axvline(loop["hydraulic_hz"], color="0.5", lw=0.8, ls=":",
                      label=f"hydraulic resonance {loop['hydraulic_hz']:.1f} Hz (undamped at rest)" if a is ax[0] else None)
    ax[0].legend(fontsize=7, loc="lower left")
    ax[0].set_ylim(max(ax[0].get_ylim()[0], -100), ax[0].get_ylim()[1])
    ax[0].set_ylabel("|L|, dB")
    ax[1].set_ylabel("phase of L, deg")
    ax[1].set_xlabel("frequency, Hz")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    ax[0].set_title(title, fontsize=9)
    return save(fig, path)
