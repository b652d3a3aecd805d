"""How long a diagnosis will take, said at its start (issue 44, point 5).

A diagnosis is almost all replays of the campaign, so its time is the time of one replay -- measured here, on this
campaign, on this machine at its load, two replays side by side as the search runs them -- times how many the
search will make, plus what does not replay.  How many depends on how far the search goes, which the book model's
figure on the fit data foretells: a campaign the book's rig nearly explains ends after the library's rounds (a
few hundred replays); one it misses by far goes on through the structural hypotheses, the states and a proposed
term (thousands).  :data:`REPLAYS` holds the counts measured (``ehas diagnose`` prints its count at the end).
"""
from __future__ import annotations

import math
import time

from ehas_env.measurement.replay import COST_SIGNALS, ModelSpec, Replayer
from ehas_env.measurement.verdict import blocks_of, grade

#: replays of a whole diagnosis by the book model's figure on the fit data (x what does not repeat): (upper end of
#: the figure, replays).  Measured at 563d7a2 on the independent generator's 5-run campaigns of 3 s: a clean one
#: (book figure 1.1) 396 replays; bore-wear friction (figure 7.0, unexplained: hypotheses, states, a term) 4530
REPLAYS = ((2.0, 400), (4.0, 1500), (math.inf, 4500))
#: seconds a diagnosis spends besides its replays at a load of one per core (the stages' own work, the written
#: figures and JSON; measured at load 2.5 a core: the clean campaign's 12.4 s less its 396 replays timed at 26 ms)
FIXED_S = 2.0
#: replays timed (side by side on the cores, as the search's batches run)
TIMED = 4


def estimate(rep: Replayer, load_scale: float = 1.0) -> dict:
    """The time a diagnosis of ``rep``'s campaign should take, and what the estimate rests on.

    Parameters
    ----------
    rep : Replayer
        The fit data (the diagnosis' own replayer: its compiled model, its runs' fit windows).
    load_scale : float
        Wall seconds per CPU second to expect for the work that does not replay
        (:func:`ehas_env.physics.codegen.load_scale`).

    Returns
    -------
    dict
        ``estimate_s`` (s), ``replay_s`` (one replay of the fit data, wall s), ``book_x_noise`` (the book model's
        figure on the fit data) and ``replays`` (the count expected).
    """
    book = ModelSpec()
    n0 = rep.n_evals
    sims = rep.simulate(book)  # a first replay compiles or loads the model: not timed
    rep.simulate_many([book, book])  # and the threads' first replays start them
    t = time.perf_counter()
    rep.simulate_many([book] * TIMED)
    replay_s = (time.perf_counter() - t) / TIMED
    rep.n_evals = n0  # the timing replays are not the search's
    figure = grade(blocks_of(rep, sims, COST_SIGNALS))["residual_x_noise"]
    replays = next(n for upper, n in REPLAYS if figure <= upper)
    return {"estimate_s": round(FIXED_S * load_scale + replays * replay_s, 1), "replay_s": round(replay_s, 4),
            "book_x_noise": round(figure, 3), "replays": replays}


def in_words(est: dict) -> str:
    """The estimate as the progress line says it.

    Examples
    --------
    >>> in_words({"estimate_s": 95.0, "replay_s": 0.02, "book_x_noise": 6.9, "replays": 4500})
    'expected: about 95 s (the book model leaves 6.9x noise on the fit data: about 4500 replays of 20 ms)'
    """
    return (f"expected: about {est['estimate_s']:.0f} s (the book model leaves {est['book_x_noise']:.2g}x noise on "
            f"the fit data: about {est['replays']} replays of {est['replay_s'] * 1e3:.0f} ms)")
