"""The README opens with the two commands, and CI runs the second one verbatim."""
from pathlib import Path
import re

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
