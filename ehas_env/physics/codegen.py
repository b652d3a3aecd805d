"""The compiled model: baseline + effects' terms + drivers, generated into one real module.

The plant is defined once: the baseline's pieces in :mod:`ehas_env.physics.baseline`,
each effect's terms in its own file (static methods named after the places of
:data:`~ehas_env.physics.effects.base.PLACES`), each compiled controller's law in
its own file.  This module writes them, with the assembled right-hand side
(``valve_current``, ``derivatives``, ``project``, ``measure``) and the compiled
parts that drive it (the one RK4 integrator, the open/closed-loop drivers and the
valve bench, the environment's step), into one Python file named by the hash of
its text, then imports it.  numba compiles that file's functions on first use and
caches them beside it, so:

* everything a step runs is one inlined compiled body (no function pointers:
  numba first-class function tuples cost ~75 % more per step here);
* a changed effect file, a new user effect or a new controller law gives a new
  text, hence a new file and a fresh compile -- a stale cache can never run;
* every simulator of the project (single env, batched env, benchmark, replay of
  logs, valve bench, linearisation) runs the same compiled functions.

Effects that are part of a model but switched off in a row of parameters are
skipped by their ``<effect>.on`` slot, so one model serves plants with any
subset of its effects (domain randomisation over effects needs this).

Examples
--------
>>> from ehas_env.physics.codegen import build_model
>>> from ehas_env.simulation.control_laws import all_laws
>>> m = build_model(laws=all_laws(), inline=False)
>>> m.STATE_NAMES[:3], "coulomb_friction.Fc" in m.IDX
(('theta', 'omega', 'qc'), True)
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import re
import sys
import textwrap
from pathlib import Path

from ehas_env.physics import baseline, layout

#: files whose part below the ``# >>> compiled`` line is copied into every model, in this order
COMPILED_PARTS = (
    "ehas_env/physics/integrator.py",
    "ehas_env/simulation/loops.py",
    "ehas_env/env/batch_kernel.py",
)
MARKER = "# >>> compiled"
_PKG_ROOT = Path(__file__).resolve().parents[2]
_MODELS: dict[str, object] = {}  # by the hash of the generated text
_BY_PARTS: dict[tuple, object] = {}  # by the effect classes and law functions it was made from


def cache_dir() -> Path:
    """Where generated models live: ``$EHAS_CACHE_DIR`` or ``~/.cache/ehas/models``."""
    env = os.environ.get("EHAS_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "ehas" / "models"


def _ident(name: str) -> str:
    return re.sub(r"\W", "_", name)


def _compiled_part(rel: str) -> str:
    text = (_PKG_ROOT / rel).read_text()
    line = "\n" + MARKER + "\n"
    if line not in text:
        raise RuntimeError(f"{rel} has no '{MARKER}' line")
    return f"# ---- {rel} " + "-" * 40 + "\n" + text.split(line, 1)[1]


def _baseline_source() -> str:
    text = inspect.getsource(baseline)
    start = text.index("@njit")
    return "# ---- ehas_env/physics/baseline.py " + "-" * 40 + "\n" + text[start:]


def _term_source(cls, place: str, fname: str) -> str:
    fn = inspect.getattr_static(cls, place)
    fn = getattr(fn, "__func__", fn)
    src = textwrap.dedent(inspect.getsource(fn))
    lines = src.splitlines()
    while lines and lines[0].lstrip().startswith("@"):
        lines.pop(0)
    src = "\n".join(lines)
    src = re.sub(r"^def\s+\w+\s*\(", f"def {fname}(", src, count=1, flags=re.M)
    where = inspect.getsourcefile(fn) or "?"
    return f"# {cls.name}.{place} ({where})\n@njit(cache=True, inline=\"always\")\n{src}\n"


class ModelSource:
    """What goes into one generated model: its effects (classes) and compiled controller laws."""

    def __init__(self, effects, laws):
        self.effects = sorted(effects, key=lambda c: c.name)
        self.laws = list(laws)
        self.states = list(layout.STATE_NAMES)
        self.state_owner: dict[str, int] = {}
        for cls in self.effects:
            for st in cls.states:
                key = f"{cls.name}.{st[0]}"
                self.state_owner[key] = len(self.states)
                self.states.append(key)
        self.slots = list(layout.BASE_SLOTS)
        for cls in self.effects:
            self.slots.extend(cls.slot_names())
        self.idx = {n: k for k, n in enumerate(self.slots)}

    # -- code of the assembled functions ---------------------------------
    def _arg(self, cls, name: str, place: str) -> str:
        kind = cls.arg_kind(name, place)
        if kind == "param":
            return f"P[{self.idx[f'{cls.name}.{name}']}]"
        if kind == "quantity":
            return name
        if kind == "state":
            return f"s[{self.state_owner[f'{cls.name}.{name}']}]"
        return f"P[{layout.BASE_SLOTS.index(name)}]"

    def _call(self, cls, place: str) -> str:
        args = ", ".join(self._arg(cls, a, place) for a in cls.term_args(place))
        return f"_t_{_ident(cls.name)}__{place}({args})"

    def _on(self, cls) -> str:
        return f"P[{self.idx[f'{cls.name}.on']}] != 0.0"

    def _with(self, place: str):
        return [c for c in self.effects if place in c.terms()]

    def source(self) -> str:
        out = ['"""Generated by ehas_env.physics.codegen: one compiled model. Do not edit; see that module."""',
               "import math", "", "import numpy as np", "from numba import njit, prange", "",
               "from ehas_env.physics.layout import *  # noqa: F401,F403  (baseline indices and outputs)", "",
               f"STATE_NAMES = {tuple(self.states)!r}", f"N_STATES = {len(self.states)}",
               f"SLOTS = {tuple(self.slots)!r}", f"N_SLOTS = {len(self.slots)}",
               "IDX = {n: k for k, n in enumerate(SLOTS)}",
               f"EFFECTS = {tuple(c.name for c in self.effects)!r}",
               f"LAWS = {tuple(name for name, _ in self.laws)!r}", "", _baseline_source(), ""]
        out.append("# ---- effect terms " + "-" * 40)
        for cls in self.effects:
            for place in cls.terms():
                out.append(_term_source(cls, place, f"_t_{_ident(cls.name)}__{place}"))
        out.append("# ---- controller laws " + "-" * 40)
        for k, (name, fn) in enumerate(self.laws):
            out.append(_term_source(type("law", (), {"name": name, "law": staticmethod(fn)}), "law", f"_law_{k}"))
        out.append(self._assembled())
        for rel in COMPILED_PARTS:
            out.append(_compiled_part(rel))
        return "\n".join(out) + "\n"

    def _assembled(self) -> str:
        L = []
        a = L.append
        a("# ---- the assembled model " + "-" * 40)
        a('@njit(cache=True, inline="always")')
        a("def control_law(law, gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max):")
        a('    """The compiled law number ``law`` (LAWS) of the controller; see ehas_env.simulation.control_laws."""')
        for k in range(len(self.laws)):
            a(f"    if law == {k}:")
            a(f"        return _law_{k}(gains, mem, t, dt, theta, r, rd, rdd, rddd, p_load, p_s, u_max)")
        a("    return 0.0")
        a("")
        a('@njit(cache=True, inline="always")')
        a("def valve_current(i_cmd, P):")
        a('    """Current that reaches the valve: amplifier clip, then the effects of the current chain, mA."""')
        a("    i = amplifier(i_cmd, P[I_IMAX])")
        a("    if P[I_EFFECTS_ON] == 0.0:")
        a("        return i")
        for cls in sorted(self._with("valve_current"), key=lambda c: (c.chain_order, c.name)):
            a(f"    if {self._on(cls)}:")
            a(f"        i = {self._call(cls, 'valve_current')}")
        a("    return i")
        a("")
        a('@njit(cache=True, inline="always")')
        a("def position_reading(x, P):")
        a('    """The piston position the LVDT reads for the true position x, m: the effects of the sensor chain."""')
        a("    if P[I_EFFECTS_ON] == 0.0:")
        a("        return x")
        for cls in sorted(self._with("position_reading"), key=lambda c: (c.chain_order, c.name)):
            a(f"    if {self._on(cls)}:")
            a(f"        x = {self._call(cls, 'position_reading')}")
        a("    return x")
        a("")
        a('@njit(cache=True, inline="always")')
        a("def valve_side_flows(qc, pa, pb, ps, P):")
        a('    """Flows into lines A and B added at the valve\'s lands by valve-side effects (Effect.valve_side),')
        a('    m^3/s: what meters in the lines read beyond the critically lapped lands\' flows."""')
        side = [c for c in self._with("chamber_flows") if c.valve_side]
        if not side:  # no valve-side effect in this model: nothing recomputed on every measurement
            a("    return 0.0, 0.0")
        else:
            a("    if P[I_EFFECTS_ON] == 0.0:")
            a("        return 0.0, 0.0")
            a("    p_load = pa - pb")
            a("    q_a, q_b, q_supply = land_flows(qc, pa, pb, ps, P[I_DROP])")
            a("    extra_a = 0.0")
            a("    extra_b = 0.0")
            for cls in side:
                a(f"    if {self._on(cls)}:")
                a(f"        dqa, dqb = {self._call(cls, 'chamber_flows')}")
                a("        extra_a += dqa")
                a("        extra_b += dqb")
            a("    return extra_a, extra_b")
        a("")
        joint = self._with("joint_force")
        a('@njit(cache=True, inline="always")')
        a("def two_body(P):")
        a('    """True when a rod-joint effect is on: piston and crank are separate bodies."""')
        a("    return " + ("P[I_EFFECTS_ON] != 0.0 and (" + " or ".join(f"({self._on(c)})" for c in joint) + ")"
                        if joint else "False"))
        a("")
        a('@njit(cache=True, inline="always")')
        a("def derivatives(s, i_valve, P, ds):")
        a('    """Right-hand side ds = f(s) for the valve current i_valve (mA, after the current chain)."""')
        a("    theta, omega, qc, qc_dot, pa, pb, ps, xp, vp = s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]")
        a("    i = i_valve")
        a("    r, A = P[I_RADIUS], P[I_AREA]")
        a("    c, sn = math.cos(theta), math.sin(theta)")
        a("    p_load = pa - pb")
        a("    valve_rates(s, i, ps, p_load, P, ds)")
        a("    q_a, q_b, q_supply = land_flows(qc, pa, pb, ps, P[I_DROP])")
        a("    if P[I_EFFECTS_ON] == 0.0:")
        a("        # the baseline alone: the general path below with every effect off, without its branches")
        a("        x, v = r * sn, r * c * omega")
        a("        ds[0] = omega")
        a("        ds[1] = crank_accel(c, sn, omega, A * p_load, 0.0, 0.0, P[I_INERTIA], r)")
        a("        ds[7] = v")
        a("        ds[8] = 0.0")
        a("        ds[4], ds[5] = chamber_rates(x, v, q_a, q_b, A, P[I_HALF_STROKE], P[I_VDEAD], P[I_BETA])")
        a("        ds[6] = 0.0")
        extra = [self.state_owner[k] for k in self.state_owner]
        for k in extra:
            a(f"        ds[{k}] = 0.0")
        a("        return")
        a("    joint = two_body(P)")
        a("    if joint:")
        a("        x, v = xp, vp")
        a("    else:")
        a("        x, v = r * sn, r * c * omega")
        a("    qa_in, qb_in = q_a, q_b")
        for cls in self._with("chamber_flows"):
            a(f"    if {self._on(cls)}:")
            a(f"        dqa, dqb = {self._call(cls, 'chamber_flows')}")
            a("        qa_in += dqa")
            a("        qb_in += dqb")
        a("    f = A * p_load")
        for cls in self._with("piston_force"):
            a(f"    if {self._on(cls)}:")
            a(f"        f += {self._call(cls, 'piston_force')}")
        a("    m = 0.0")
        for cls in self._with("moving_mass"):
            a(f"    if {self._on(cls)}:")
            a(f"        m += {self._call(cls, 'moving_mass')}")
        a("    tq = 0.0")
        for cls in self._with("crank_torque"):
            a(f"    if {self._on(cls)}:")
            a(f"        tq += {self._call(cls, 'crank_torque')}")
        a("    if joint:")
        a("        gap = xp - r * sn")
        a("        gap_rate = vp - r * c * omega")
        a("        f_joint = 0.0")
        a("        m_min = 0.0")
        for cls in joint:
            a(f"        if {self._on(cls)}:")
            a(f"            f_joint += {self._call(cls, 'joint_force')}")
            if any(p.name == "m_min" for p in cls.constants):
                a(f"            m_min = max(m_min, P[{self.idx[cls.name + '.m_min']}])")
        a("        ds[7] = vp")
        a("        ds[8] = (f - f_joint) / max(m, m_min)")
        a("        ds[0] = omega")
        a("        ds[1] = (f_joint * r * c + tq) / P[I_INERTIA]")
        a("    else:")
        a("        ds[0] = omega")
        a("        ds[1] = crank_accel(c, sn, omega, f, tq, m, P[I_INERTIA], r)")
        a("        ds[7] = v")
        a("        ds[8] = 0.0  # slaved to the crank; set after each step")
        a("    ds[4], ds[5] = chamber_rates(x, v, qa_in, qb_in, A, P[I_HALF_STROKE], P[I_VDEAD], P[I_BETA])")
        a("    ds[6] = 0.0")
        for cls in self._with("supply_rate"):
            a(f"    if {self._on(cls)}:")
            a(f"        ds[6] += {self._call(cls, 'supply_rate')}")
        for cls in self.effects:
            if not cls.states:
                continue
            ks = [self.state_owner[f"{cls.name}.{st[0]}"] for st in cls.states]
            for k in ks:
                a(f"    ds[{k}] = 0.0")
            if "state_rates" in cls.terms():
                a(f"    if {self._on(cls)}:")
                call = self._call(cls, "state_rates")
                if len(ks) == 1:
                    a(f"        ds[{ks[0]}] = {call}")
                else:
                    a(f"        _r = {call}")
                    for j, k in enumerate(ks):
                        a(f"        ds[{k}] = _r[{j}]")
        a("")
        return "\n".join(L) + "\n"


def build_model(effects=None, laws=(), inline: bool = True):
    """The compiled model module of ``effects`` and the controller ``laws``.

    Writes the generated file on first use (atomically) and imports it; later
    calls with the same text return the loaded module.

    Parameters
    ----------
    effects : list of Effect classes, optional
        The effects the model holds (default: every registered effect).
    laws : sequence of (name, function)
        The compiled controller laws, numbered in this order (the simulation layer's registry,
        :func:`ehas_env.simulation.control_laws.all_laws`, gives them).
    inline : bool
        Inline every model function into the drivers (fastest step, longest compile) or compile each once.

    Returns
    -------
    module
        The generated model module.
    """
    from ehas_env.physics.effects import REGISTRY

    effects = list(REGISTRY.values()) if effects is None else list(effects)
    laws = list(laws)
    # the same classes and laws give the same text: skip regenerating it (every Plant asks for its model)
    key = (tuple(effects), tuple(laws), bool(inline))
    if key in _BY_PARTS:
        return _BY_PARTS[key]
    spec = ModelSource(effects, laws)
    text = spec.source()
    if not inline:
        text = text.replace('@njit(cache=True, inline="always")', "@njit(cache=True)")
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    if digest in _MODELS:
        _BY_PARTS[key] = _MODELS[digest]
        return _MODELS[digest]
    name = f"ehas_model_{digest}"
    folder = cache_dir()
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text() != text:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f".{name}.{os.getpid()}.tmp"
        tmp.write_text(text)
        os.replace(tmp, path)
        if os.environ.get("EHAS_QUIET_COMPILE") != "1":
            _watch_compiles(name, inline)  # announced when numba starts compiling it (numba compiles lazily)
    mspec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(mspec)
    sys.modules[name] = module
    mspec.loader.exec_module(module)
    module.SPEC = spec
    _MODELS[digest] = module
    _BY_PARTS[key] = module
    return module


#: measured CPU seconds to compile what a command first runs of each build (results/compile.md, compile_quiet.md)
COMPILE_CPU_S = {True: 60.0, False: 10.0}
_WATCH = {"depth": 0, "start": 0.0, "name": "", "thread": None, "est": 0.0}
HEARTBEAT_S = 10.0
_FRESH: dict[str, bool] = {}  # generated modules written by this process and not yet compiled: their build


def compile_estimate_s(inline: bool) -> float:
    """Seconds a first compile of the ``inline`` build should take now: the quiet figure scaled by the load.

    Parameters
    ----------
    inline : bool
        The build (see :func:`current_model`).

    Returns
    -------
    float
        ``COMPILE_CPU_S[inline]`` times the run queue per core when above one (2 loaded cores share it).
    """
    try:
        load = os.getloadavg()[0] / max(1, os.cpu_count() or 1)
    except OSError:
        load = 1.0
    return COMPILE_CPU_S[bool(inline)] * max(1.0, load)


def _watch_compiles(module: str, inline: bool) -> None:
    """Announce the first compile of the new generated ``module`` and print a line every HEARTBEAT_S while
    numba compiles (numba's compile events say when it does; a cached function's load is one too, hence only
    modules whose file was just written are announced)."""
    import threading
    import time

    from numba.core import event

    _FRESH[module] = inline
    if _WATCH["thread"] is not None:
        return

    class _Listener(event.Listener):
        def on_start(self, ev):
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            if _WATCH["depth"] == 0:
                _WATCH["start"] = time.monotonic()
                _WATCH["name"] = getattr(fn, "__name__", "?")
                mod = getattr(fn, "__module__", "")
                if mod in _FRESH:
                    inl = _FRESH.pop(mod)
                    _WATCH["est"] = compile_estimate_s(inl)
                    build = "fast-step build" if inl else "quick-compile build"
                    print(f"ehas: compiling the simulator for this set of effects and controllers ({build}, "
                          f"{_WATCH['name']}; first run only; about {_WATCH['est']:.0f} s at this machine's load)",
                          file=sys.stderr, flush=True)
            _WATCH["depth"] += 1

        def on_end(self, ev):
            _WATCH["depth"] = max(0, _WATCH["depth"] - 1)

    def beat():
        said = 0  # heartbeats printed for the compile under way
        while True:
            time.sleep(1.0)
            if _WATCH["depth"] == 0:
                said = 0
                continue
            spent = time.monotonic() - _WATCH["start"]
            if spent >= (said + 1) * HEARTBEAT_S:
                said = int(spent // HEARTBEAT_S)
                print(f"ehas: still compiling the simulator ({_WATCH['name']}): {spent:.0f} s so far, "
                      f"about {_WATCH['est']:.0f} s in all", file=sys.stderr, flush=True)

    event.register("numba:compile", _Listener())
    _WATCH["thread"] = threading.Thread(target=beat, name="ehas-compile-heartbeat", daemon=True)
    _WATCH["thread"].start()
