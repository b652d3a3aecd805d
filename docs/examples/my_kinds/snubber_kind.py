"""A kind of my own: a one-way lag (a gauge snubber with a check valve), put at every signal place of the model."""
from ehas_env.physics.augment import SIGNAL_PLACES, Follower
from ehas_env.physics.effects.base import Param


class OneWayLag(Follower):
    """A lag that rises fast and falls slowly: a gauge line that fills through a check valve and drains through
    the snubber's orifice."""

    form = "a one-way lag"
    stem = "snub"
    kind_title = "one-way lag (snubber with a check valve)"
    law = "d / T_up if d > 0.0 else d / T_down"
    params = (Param("T_down", "ms", 5.0, (0.05, 100.0), "falling time constant: the snubber's orifice",
                    typical=(1.0, 20.0), si=1.0e-3, log_scale=True),
              Param("T_up", "ms", 0.1, (0.05, 100.0), "rising time constant: through the check valve",
                    typical=(0.05, 1.0), si=1.0e-3, log_scale=True))
    main_param = "T_down"
    explanation = "The reading follows a rise at once and a fall with the time constant T_down."
    signature = "a residual at every fall of the signal alone, the reading above the truth; none while it rises."


SNUBBERS = [OneWayLag.at(place) for place in SIGNAL_PLACES]
