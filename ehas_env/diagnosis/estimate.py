"""How long a diagnosis will take, said at its start (issue 44, point 5).

A diagnosis is almost all replays of the campaign, so its time is the time of one replay -- measured here, on this
campaign, on this machine at its load, two replays side by side as the search runs them -- times how many the
search will make, plus what does not replay.  How many depends on how far the search goes, which two things
foretell: the book model's figure on the fit data (a campaign the book's rig nearly explains ends after the
library's rounds, a few hundred replays; one it misses by far goes on through the structural hypotheses, the
states and a proposed term, thousands), and whether one library effect alone, its main parameter at the values the
screen scans first, takes most of that miss away (the library's rounds then end it: :func:`library_share`, about
120 replays in one batch), or whether the logged supply pressure, taken as a measured input, does (one replay:
:func:`measured_input_figure`).  :data:`REPLAYS`, :data:`LIBRARY_REPLAYS` and :data:`MEASURED_INPUT_REPLAYS` hold
the counts measured (``ehas
diagnose`` prints its count at the end).  A replay beyond the library's first rounds costs more than the one timed
(:data:`SEARCH_REPLAY_COST`): its models carry more (a structural hypothesis, a missing state, a term) and a share
of them replays every run at full length.
"""
from __future__ import annotations

import math
import time

from ehas_env.diagnosis.measured_inputs import measured, residual_x_noise, variation
from ehas_env.measurement.replay import COST_SIGNALS, ModelSpec, Replayer
from ehas_env.measurement.verdict import BLOCK_EXPLAINED_X, blocks_of, grade

#: replays of a whole diagnosis by the book model's figure on the fit data (x what does not repeat): (upper end of
#: the figure, replays).  Measured on the independent generator's 5-run campaigns of 3 s: a clean one (book figure
#: 1.1) 396 replays at 563d7a2; the drawn set, all 38 cases at f8075c9 (results/diagnosis_drawn, the sum of the
#: stages' ``replays``): figure 2-4, median 1352 (962-5829, 22 cases, the five below also counted); above 4, median
#: 3467 (1320-8105, 16 cases).  A figure at or below 2 with a run and signal above what the verdict calls
#: explained (:data:`~ehas_env.measurement.verdict.BLOCK_EXPLAINED_X`) goes on through the hypotheses and the states
#: as one between 2 and 4 does
REPLAYS = ((2.0, 400), (4.0, 1350), (math.inf, 3470))
#: replays of a diagnosis the library's effects end (measured: Coulomb friction of 600 N hidden, book figure 19,
#: explained after the library's rounds: 993), and the share of the book model's excess over the noise (in the
#: log cost) the best library effect alone may leave at its best scanned value for that path to be foretold
#: (measured: 0.013 there, 0.17-0.23 for a Coulomb friction between two of the scan's values, a factor 2 apart;
#: 0.62-1.0 on a clean campaign, a return line at 20 bar and three campaigns the library leaves unexplained; the
#: drawn set's three at 0.28-0.33 went on to 2953-6753 replays, none ended by the library)
LIBRARY_REPLAYS, LIBRARY_SHARE = 1000, 0.25
#: replays of a diagnosis that a logged supply taken as a measured input ends (the library's rounds and the
#: structural hypotheses find nothing, the input explains the campaign, no state is looked for).  Measured on the
#: start-conditions set's pump ripple of 10 bar at 23.7 Hz (results/verdict_start_conditions, at 5f4951f): 755,
#: 802 and 779 replays for the faded-in, the from-rest and the knocked campaigns; and the share of the book model's
#: figure the input may leave for that path to be foretold (its figure with the input at or below the top of
#: :data:`REPLAYS`' first class: a campaign the book's rig then nearly explains)
MEASURED_INPUT_REPLAYS = 800
#: seconds a diagnosis spends besides its replays at a load of one per core (the stages' own work, the written
#: figures and JSON; measured at load 2.5 a core: the clean campaign's 12.4 s less its 396 replays timed at 26 ms)
FIXED_S = 2.0
#: what a replay beyond the first :data:`REPLAYS` ``[0][1]`` (a clean campaign's whole diagnosis, the library's
#: rounds: replays as timed) costs, in replays timed here: its models carry more (a structural hypothesis, a block
#: with a state: the larger model, 44 % slower a replay) and a share of them replays every run at full length.
#: Measured on the drawn set at f8075c9 (each diagnosis on an empty model cache, its replays on the C drivers:
#: the time less 400 replays as timed, over its other replays): median 1.78 (0.91-2.26).  With it and the counts
#: above the estimate of 31 of the 38 is within a factor 2 of the time taken (29 with the constants before, 2.4
#: and 1500 / 4300, set when numba compiled the larger model inside the search): in-sample, the drawn set's own
#: figures (``python -m tests.measurement.diagnosis_speed --part sets`` judges stored records)
SEARCH_REPLAY_COST = 1.78
#: replays timed (side by side on the cores, as the search's batches run)
TIMED = 4


def library_share(rep: Replayer, book_cost: float, candidates=None) -> tuple:
    """The share of the book model's excess over the noise (log cost) the best library effect leaves alone, each
    effect's main parameter at the values its screen scans first (:func:`~ehas_env.diagnosis.fitting.scan_values`),
    replayed in one batch; and that effect.

    Parameters
    ----------
    rep : Replayer
    book_cost : float
        The book model's log cost on ``rep``.
    candidates : list of str, optional
        The library effects the diagnosis tries (default every one).

    Returns
    -------
    (float, str or None)
    """
    from ehas_env.diagnosis.candidates import library_effects
    from ehas_env.diagnosis.fitting import model_from, own_params, scan_values, start_value
    from ehas_env.physics.effects import get_effect

    models, names = [], []
    for effect in candidates if candidates is not None else library_effects():
        free = own_params(effect)
        main = next((fp for fp in free if fp.name == get_effect(effect).main_param), None)
        if main is None:
            continue
        start = {(fp.effect, fp.name): start_value(fp) for fp in free}
        for v in scan_values(main):
            models.append(model_from(free, {**start, (effect, main.name): v}, ModelSpec()))
            names.append(effect)
    if not models or book_cost <= 1.0:
        return 1.0, None
    costs = [rep.log_cost(sims) for sims in rep.simulate_many(models)]
    best = min(range(len(costs)), key=lambda k: costs[k])
    return max(costs[best] - 1.0, 0.0) / (book_cost - 1.0), names[best]


def estimate(rep: Replayer, load_scale: float = 1.0, candidates=None) -> dict:
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
        figure on the fit data), ``replays`` (the count expected), ``load_scale`` (as given),
        ``library_share_left`` and ``library_effect`` (:func:`library_share`) and ``measured_input_x_noise``
        (:func:`measured_input_figure`, None when not asked).
    """
    book = ModelSpec()
    n0 = rep.n_evals
    sims = rep.simulate(book)  # a first replay compiles or loads the model: not timed
    rep.simulate_many([book, book])  # and the threads' first replays start them
    t = time.perf_counter()
    rep.simulate_many([book] * TIMED)
    replay_s = (time.perf_counter() - t) / TIMED
    g = grade(blocks_of(rep, sims, COST_SIGNALS))
    figure = g["residual_x_noise"]
    replays = next(n for upper, n in REPLAYS if figure <= upper)
    if replays == REPLAYS[0][1] and g["worst"] and g["worst"]["residual_x_noise"] > 1.0 + BLOCK_EXPLAINED_X:
        replays = REPLAYS[1][1]  # a miss in one run and signal: the search goes on (hypotheses, states)
    share, effect = (1.0, None)
    with_input = measured_input_figure(rep) if replays > REPLAYS[0][1] else None
    if with_input is not None and with_input <= REPLAYS[0][0]:  # the logged supply, taken as an input, ends it
        replays = MEASURED_INPUT_REPLAYS
    elif replays > REPLAYS[0][1]:  # beyond a recalibration: would one library effect end it?
        share, effect = library_share(rep, rep.log_cost(sims), candidates)
        if share <= LIBRARY_SHARE:
            replays = LIBRARY_REPLAYS
    rep.n_evals = n0  # the timing and probing replays are not the search's
    return {"estimate_s": round(seconds(replays, replay_s, load_scale), 1), "replay_s": round(replay_s, 4),
            "book_x_noise": round(figure, 3), "replays": replays, "load_scale": round(load_scale, 3),
            "library_share_left": round(share, 3), "library_effect": effect,
            "measured_input_x_noise": None if with_input is None else round(with_input, 3)}


def measured_input_figure(rep: Replayer) -> float | None:
    """The book model's figure on ``rep`` with the logged supply pressure taken as a measured input
    (:func:`ehas_env.diagnosis.measured_inputs.measured`), the supply left out of the comparison as the diagnosis'
    stage leaves it; None when no run logs a supply that varies beyond its noise (the stage would not try it).

    Parameters
    ----------
    rep : Replayer

    Returns
    -------
    float or None
    """
    var = variation(rep, "p_s_bar")
    if not var or not var["varies"]:
        return None
    mrep = measured(rep, ("p_s_bar",))
    return residual_x_noise(mrep, mrep.simulate(ModelSpec()), without=("p_s_bar",))


def seconds(replays: int, replay_s: float, load_scale: float = 1.0) -> float:
    """The time of a diagnosis that makes ``replays`` replays of ``replay_s`` each (as timed): the first
    :data:`REPLAYS` ``[0][1]`` as timed, the rest at :data:`SEARCH_REPLAY_COST` times that, plus :data:`FIXED_S`
    scaled by the load.

    Parameters
    ----------
    replays : int
        Replays the search is expected to make.
    replay_s : float
        One replay of the fit data as timed (wall s).
    load_scale : float
        Wall seconds per CPU second of the work that does not replay.

    Returns
    -------
    float
        Seconds.

    Examples
    --------
    >>> round(seconds(400, 0.03), 1), round(seconds(1400, 0.03), 1)
    (14.0, 67.4)
    """
    first = min(replays, REPLAYS[0][1])
    return FIXED_S * load_scale + replay_s * (first + SEARCH_REPLAY_COST * (replays - first))


def in_words(est: dict) -> str:
    """The estimate as the progress line says it.

    Examples
    --------
    >>> in_words({"estimate_s": 95.0, "replay_s": 0.02, "book_x_noise": 6.9, "replays": 4500})
    'expected: about 95 s (the book model leaves 6.9x noise on the fit data: about 4500 replays of 20 ms)'
    """
    return (f"expected: about {est['estimate_s']:.0f} s (the book model leaves {est['book_x_noise']:.2g}x noise on "
            f"the fit data: about {est['replays']} replays of {est['replay_s'] * 1e3:.0f} ms)")
