"""Convert a pickled agent folder (``model.zip``, ``vecnormalize.pkl``) to the data-only format.

``python -m ehas_train.agent_convert FOLDER [FOLDER ...] [--remove-pickles]`` unpickles each
folder once (do it only for an agent you trust: unpickling runs whatever code the files hold),
writes ``policy.safetensors``, ``policy.json`` and ``obs_norm.json`` beside ``config.json``
(docs/agents.md), and checks that the converted agent's actions equal the pickled one's bit
for bit on 4096 observations spread over the observation box; ``--remove-pickles`` then
deletes ``model.zip`` and ``vecnormalize.pkl``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def convert(folder, remove_pickles: bool = False, samples: int = 4096) -> int:
    """Convert one agent folder; returns the number of observations checked equal.

    Parameters
    ----------
    folder : path
        A pickled agent folder written by ``ehas train``.
    remove_pickles : bool
        Delete ``model.zip`` and ``vecnormalize.pkl`` after the check.
    samples : int
        Observations on which converted and pickled actions must be identical.

    Returns
    -------
    int
        ``samples``.
    """
    from . import agent_format as AF
    from .agent import _load_pickled, load_agent

    folder = Path(folder)
    old = _load_pickled(folder, warn=False)
    AF.write_safe(folder, old.model, old.obs_stats)
    new = load_agent(folder)
    rng = np.random.default_rng(0)
    space = new.model.observation_space
    obs = rng.uniform(np.maximum(space.low, -3.0), np.minimum(space.high, 3.0), (samples,) + space.shape)
    if old.obs_stats is not None:  # around the training distribution too: raw observations from the statistics
        raw = old.obs_stats.obs_rms.mean + np.sqrt(old.obs_stats.obs_rms.var) * rng.standard_normal(obs.shape)
        obs = np.concatenate([obs, raw]).astype(np.float32)
    a, b = old.predict(obs), new.predict(obs)
    if not np.array_equal(a, b):
        raise ValueError(f"{folder}: the converted agent acts differently (max |diff| {np.max(np.abs(a - b)):.3g}); "
                         "the pickles are kept")
    if remove_pickles:
        for name in ("model.zip", "vecnormalize.pkl"):
            (folder / name).unlink(missing_ok=True)
    return len(obs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ehas_train.agent_convert", description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+")
    ap.add_argument("--remove-pickles", action="store_true", help="delete model.zip and vecnormalize.pkl after "
                    "the converted agent is checked to act identically")
    args = ap.parse_args(argv)
    for f in args.folders:
        n = convert(f, args.remove_pickles)
        print(f"{f}: policy.safetensors, policy.json, obs_norm.json written; actions identical on {n} observations")
    return 0


if __name__ == "__main__":
    sys.exit(main())
