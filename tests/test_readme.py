"""The README opens with the two commands, and CI runs the second one verbatim; every command block of the
README and docs/*.md runs as written in a clone of the repository and leaves its ``git status`` clean.

The sweep clones the repository (its committed files; the package runs from its installation, this checkout)
and runs each command of every ```bash block in order, with ``bash``, in the clone's root.  Commands are taken
as written; the few long ones get the fast flags of :data:`FAST` appended (stated here, one per command), and the
commands that cannot run on a test machine are in :data:`EXCLUDED`, each with its reason.  The default suite
runs the quick commands (:data:`QUICK`); the whole sweep is marked slow (about 10 min on 2 cores).
"""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command():
    blocks = re.findall(r"```bash\n(.*?)\n```", (ROOT / "README.md").read_text(), flags=re.S)
    assert len(blocks) >= 2
    install_and_demo, install_and_test = blocks[0].strip(), blocks[1].strip()
    assert "ehas demo" in install_and_demo
    assert "pytest" in install_and_test
    ci_lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert install_and_test in ci_lines
    # torch's CPU wheel goes in before stable-baselines3 pulls a CUDA build
    assert install_and_test.index("torch==") < install_and_test.index(".[rl")


# -- every command block of README.md and docs/*.md runs as written in a clone and leaves it clean ---------------

#: commands not run, each with why (matched as a substring after whitespace is normalised); keep this short
EXCLUDED = {
    "python -m pip install": "installs the package (the test runs the installed one)",
    "pip install": "installs the package (the test runs the installed one)",
    "python -m pytest": "the test suite itself",
    "ray ": "starts or queries a Ray cluster on other machines (--executor ray --address auto too)",
    "ehas train": "hours of training (tests/train runs short trainings)",
    "python -m ehas_train.time_to_beat": "trains until the learned controller wins (hours)",
    "python -m tests.independent_rig.acceptance": "the open-world acceptance campaign (hours; resumable)",
    "python -m tests.independent_rig.campaign OUT": "a template: OUT and [--rig rig_b] are placeholders",
    "ehas diagnose my_campaign": "needs the user's campaign the page assumes",
    "ehas compare my_campaign": "needs the user's campaign the page assumes",
    "ehas effects torsion_spring": "needs the effect file the page writes in prose (my_effects/)",
    "ehas simulate --effects-path my_effects": "needs the effect file the page writes in prose (my_effects/)",
    "ehas bench results/controllers/schedule_optimize.json --effects-path my_effects": "needs my_effects/ (prose)",
    "ehas bench my_controllers/my_pd.py": "needs the controller file the page writes in prose (my_controllers/)",
    "ehas simulate --controller my_controllers/my_pd.py": "needs the controller file the page writes in prose",
    "ehas model diff runs/myrig.json calibrated.json": "exits 1 by design when the files differ; calibrated.json is "
                                                       "the user's",
}
#: long commands and the flags that make them fast (appended); the command is otherwise run as written
FAST = {
    "ehas demo": "--quick",  # the full demo is results/demo's own command (about a minute)
    "ehas perf": "--seconds 0.2 --repeats 1 --sizes 1,64 --training-steps 0 --rss-envs 0",
    "python -m ehas_train.versus": "--no-robustness",
}
#: commands that run in the default suite (seconds each); the rest runs in the slow sweep
QUICK = ("ehas model ", "ehas effects", "ehas excite", "ehas identify")


def doc_commands() -> list[tuple[str, str]]:
    """(page, command) of every ```bash block of README.md and docs/*.md, in order (continuations joined,
    comments dropped, ``&&`` chains kept whole)."""
    out = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for block in re.findall(r"```bash\n(.*?)\n```", page.read_text(encoding="utf-8"), flags=re.S):
            for line in block.replace("\\\n", " ").splitlines():
                for part in line.split("#")[0].split(" && "):
                    if part.strip():
                        out.append((page.name, " ".join(part.split())))
    return out


def excluded(cmd: str) -> str | None:
    return next((why for pre, why in EXCLUDED.items() if pre in cmd), None)


def clone_of_the_working_tree(dest: Path) -> Path:
    """A git clone of the repository with the working tree's changes (modified and new files that git does not
    ignore) committed on top, so that ``git status`` there starts clean and shows what the commands leave."""
    subprocess.run(["git", "clone", "-q", str(ROOT), str(dest)], check=True)
    changed = subprocess.run(["git", "ls-files", "-m", "-o", "--exclude-standard", "-z"], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout.split("\0")
    for rel in filter(None, changed):
        src, dst = ROOT / rel, dest / rel
        if src.is_file():
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
        elif not src.exists() and dst.exists():
            dst.unlink()
    git = ["git", "-c", "user.name=test", "-c", "user.email=test@localhost"]
    subprocess.run([*git, "add", "-A"], cwd=dest, check=True)
    subprocess.run([*git, "commit", "-q", "--allow-empty", "-m", "the working tree"], cwd=dest, check=True)
    return dest


def run_in_clone(commands, tmp_path):
    """Run ``commands`` in order in :func:`clone_of_the_working_tree` and return its ``git status --porcelain``
    (the package runs from its installation: this checkout, editable)."""
    clone = clone_of_the_working_tree(tmp_path / "clone")
    env = dict(os.environ)
    for page, cmd in commands:
        fast = next((f for pre, f in FAST.items() if cmd.startswith(pre)), "")
        r = subprocess.run(f"{cmd} {fast}".strip(), shell=True, cwd=clone, env=env, capture_output=True, text=True,
                           timeout=1800)
        assert r.returncode == 0, f"{page}: `{cmd}` failed (status {r.returncode}): {r.stderr.strip()[-1500:]}"
    return subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True,
                          check=True).stdout


def test_every_doc_command_is_run_or_excluded_with_a_reason():
    cmds = doc_commands()
    assert len(cmds) > 20
    used = {pre for pre in EXCLUDED if any(pre in c for _, c in cmds)}
    assert used == set(EXCLUDED), f"exclusions that match no command any more: {set(EXCLUDED) - used}"
    assert not [c for _, c in cmds if not excluded(c) and re.search(r"\bresults/[\w/.-]*\s*$|--out results", c)], \
        "a documented command writes into the committed results/"


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs git and a checkout")
def test_the_quick_doc_commands_run_in_a_clone_and_leave_it_clean(tmp_path):
    cmds = [(p, c) for p, c in doc_commands() if not excluded(c) and c.startswith(QUICK)]
    assert len(cmds) >= 5
    status = run_in_clone(cmds, tmp_path)
    assert status == "", f"the commands left the clone dirty:\n{status}"


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs git and a checkout")
def test_every_doc_command_runs_in_a_clone_and_leaves_it_clean(tmp_path):
    """The full sweep: every command not excluded, long ones with their FAST flags (about 10 min on 2 cores)."""
    cmds = [(p, c) for p, c in doc_commands() if not excluded(c)]
    status = run_in_clone(cmds, tmp_path)
    assert status == "", f"the commands left the clone dirty:\n{status}"
