"""``ehas demo``: the main job on embedded defaults.

Writes ``ehas-demo/`` in the current folder (or ``--out``; the repository's
committed ``results/demo/`` is ``ehas demo --out results/demo``): the book's sizing summary, a simulated
run of the design point (+-30 deg, 3 Hz, 7 disc sets) with its plot, and - where
those parts are installed - the tuned controller's benchmark on the book's rig
conditions and a diagnosis of a campaign with a hidden effect.  Its
``README.md`` says what each file is and the command that regenerated it.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import time
from pathlib import Path

#: where ``ehas demo`` writes unless told: the current folder, never the repository's committed results
DEFAULT_OUT = "ehas-demo"

# (title, module, function): sections contributed by the other parts of the
# project; each function takes the output folder and returns markdown.
SECTIONS = (
    ("Tuned classical controller on the book's rig conditions", "ehas_controllers.benchmark", "demo_section"),
    ("Model vs measurement: diagnosing a campaign with a hidden effect", "ehas_env.cli.diagnose", "demo_section"),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default=DEFAULT_OUT,
                        help=f"output folder (default {DEFAULT_OUT}/ in the current folder; the repository's committed "
                             "demo is --out results/demo)")
    parser.add_argument("--quick", action="store_true", help="only the sizing and the design-point run")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a non-empty --out that is not an earlier demo (an earlier demo is replaced anyway)")


def sizing_section(out: Path) -> str:
    from ehas_env.cli.main import main as cli_main
    from ehas_env.output.files import atomic_write_text

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = cli_main(["size", "--table", "design"])
    if rc != 0:  # its own error line is on stderr already
        raise RuntimeError(f"the sizing section failed (ehas size --table design: status {rc})")
    atomic_write_text(out / "sizing.txt", buf.getvalue())
    return "```\n" + buf.getvalue().rstrip() + "\n```\n\nFull tables: `ehas size` (tables 1.1-1.6, rig tests, NAS 1638)."


def design_point_section(out: Path) -> str:
    from ehas_env.simulation.plant import Plant, RigController
    from ehas_env.output.plots import plot_run
    from ehas_env.simulation.sensors import Sensors

    plant = Plant(disc_sets=7, sensors=Sensors(), seed=0)
    gains = RigController.book()
    res = plant.simulate_closed_loop(gains, amplitude_deg=30.0, freq_hz=3.0, cycles=5)
    from ehas_env.measurement.runfile import write_result
    csv_path, _ = write_result(res, out / "design_point", notes="ehas demo: book gains at the design point")
    plot_run(res, out / "design_point.png", title="design point +-30 deg, 3 Hz, 7 disc sets: book rig model (no effects, sensor noise), "
             f"book gains (Kp {gains.Kp:g} mA/deg, Ki {gains.Ki:g} mA/(deg s), Kv, Ka feed-forward)")
    err = res.tracking_errors()
    steady = res.t >= 1.0 / 3.0
    return (
        f"{plant!r}, book gains Kp {gains.Kp:g} mA/deg, Ki {gains.Ki:g} mA/(deg s), Kv {gains.Kv:.5f} mA/(deg/s), "
        f"Ka {gains.Ka:.3g} mA/(deg/s^2); sensors: 16-bit ADC, 12-bit DAC, noise.\n\n"
        f"| metric | value |\n|---|---|\n"
        f"| rms % position error (whole cycles after the first) | {err['rms_error_pct']:.2f} % |\n"
        f"| peak % position error | {err['peak_error_pct']:.2f} % |\n"
        f"| peak current | {abs(res.current_mA).max():.1f} mA |\n"
        f"| peak load pressure | {abs(res.p_a_bar - res.p_b_bar)[steady].max():.1f} bar (book table 1.3: 150.36 bar) |\n"
        f"| peak valve flow | {abs(res.flow_lpm)[steady].max():.1f} LPM (book: 22.65 LPM) |\n"
        f"| stroke end touched | {'yes' if res.hit_stroke_end else 'no'} |\n\n"
        f"Files: `{csv_path.name}` (+ `.json`, measurement format), `design_point.png`."
    )


def run(args) -> int:
    from ehas_env.output.outputs import OutputSet

    final = Path(args.out)
    # `ehas demo` regenerates its own folder (the README's first command, on a checkout that ships
    # results/demo): an earlier demo is replaced as a whole; anything else needs --overwrite
    outputs = OutputSet(final, "--out", overwrite=args.overwrite or _is_demo(final))
    with outputs as out:
        _run(args, out)
        _relocate(out, final)
    print(f"[demo] wrote {final / 'README.md'}")
    return 0


def _is_demo(folder: Path) -> bool:
    try:
        return (folder / "README.md").read_text(encoding="utf-8").startswith("# ehas demo")
    except (OSError, UnicodeDecodeError):
        return False


def _relocate(tmp: Path, final: Path) -> None:
    """Text that names the temporary folder names the output folder instead (it is swapped in there)."""
    from ehas_env.output.files import atomic_write_text

    for f in tmp.rglob("*"):
        if f.is_file() and f.suffix in (".md", ".json", ".txt", ".csv"):
            text = f.read_text(encoding="utf-8", errors="surrogateescape")
            if str(tmp) in text:
                atomic_write_text(f, text.replace(str(tmp), str(final)))


#: commands of a section's "Regenerate:" line that write into the demo's own (existing) folders
_REWRITES = ("ehas simulate-campaign ", "ehas diagnose ")


def _runnable_regenerate(body: str) -> str:
    """A section's ``Regenerate:`` commands run as written after the demo: they replace the demo's
    own campaign and diagnosis folders, which exist then, so they need ``--overwrite``.

    >>> _runnable_regenerate("Regenerate: `ehas diagnose c --out d` then `ehas diagnose e --overwrite`")
    'Regenerate: `ehas diagnose c --out d --overwrite` then `ehas diagnose e --overwrite`'
    """
    import re

    def fix(line: str) -> str:
        if not line.lstrip().startswith("Regenerate"):
            return line
        return re.sub(r"`((?:%s)[^`]*)`" % "|".join(map(re.escape, _REWRITES)),
                      lambda m: f"`{m.group(1)}`" if "--overwrite" in m.group(1).split() else f"`{m.group(1)} --overwrite`",
                      line)

    return "\n".join(fix(line) for line in body.split("\n"))


def _run(args, out: Path) -> None:
    from ehas_env.output.files import atomic_write_text

    regen = "ehas demo" + (" --quick" if args.quick else "") + (f" --out {args.out}" if args.out != DEFAULT_OUT else "")
    parts = ["# ehas demo", "", f"Regenerate with `{regen}` (this folder as a whole; the commands of each section "
             "below regenerate its part).", ""]
    plan = [("Sizing (book chapter 1)", sizing_section), ("Design point, simulated", design_point_section)]
    if not args.quick:
        for title, module_name, func in SECTIONS:
            try:
                module = importlib.import_module(module_name)
            except ModuleNotFoundError:
                continue
            if hasattr(module, func):
                plan.append((title, getattr(module, func)))
    from ehas_env.output.progress import status, working

    status(f"{len(plan)} sections into {out} (about 30 s on two quiet cores, compile included; --quick: the first two only)", "demo")
    for k, (title, section) in enumerate(plan):
        t0 = time.perf_counter()
        with working(f"{k + 1}/{len(plan)} {title}", "demo"):
            body = section(out).strip()
        if body.startswith("#"):  # the section's own title: ours stands above it
            body = body.split("\n", 1)[1] if "\n" in body else ""
        body = _runnable_regenerate(body)
        parts += [f"## {title}", "", body.strip(), "", f"_({time.perf_counter() - t0:.1f} s)_", ""]
        atomic_write_text(out / "README.md", "\n".join(parts))
