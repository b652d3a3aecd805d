"""A kind of my own: play in a signal path, put at every signal place of the model."""
from ehas_env.physics.augment import SIGNAL_PLACES, Follower
from ehas_env.physics.effects.base import Param


class Play(Follower):
    """Play in a signal path: what passes on moves only once what comes is half the width w away from it."""

    form = "a play"
    stem = "play"
    kind_title = "play"
    law = "math.copysign(max(abs(d) - 0.5 * w, 0.0), d) / T_play"
    constants = (Param("T_play", "s", 3.0e-4, (1.0e-5, 1.0e-2),
                       "how fast the far side catches up once the play is taken (assumed: 3 integrator sub-steps)"),)
    main_param = "w"
    explanation = "A play of width w: the signal passed on stays put until what comes is w/2 away, then follows."
    signature = "a flat spot in the reading at every reversal, w wide, the same at every frequency."

    @classmethod
    def kind_params(cls, place):
        return (Param("w", place.unit, 0.01 * place.span, (1.0e-4 * place.span, 0.1 * place.span),
                      f"width of the play, {place.unit} (assumed range: 0.01 % to 10 % of the signal's span)",
                      typical=(1.0e-3 * place.span, 0.03 * place.span), log_scale=True),)


PLAYS = [Play.at(place) for place in SIGNAL_PLACES]
