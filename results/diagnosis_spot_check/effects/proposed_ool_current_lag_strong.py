"""proposed_ool_current_lag_strong: lag of the valve's coil current behind the command (torque-motor inductance), found by ehas diagnose on /tmp/sc_work/ool_current_lag_strong/campaign.

The valve's coil current lags the command: a first-order lag of 6 ms (corner 26.5 Hz), the torque motor's inductance against its drive.
T = 5.998 ms (95 % CI 5.994 to 6.002)
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedOolCurrentLagStrong(Effect):
    name = "proposed_ool_current_lag_strong"
    title = "lag of the valve's coil current behind the command (torque-motor inductance)"
    params = (
        Param("T", "ms", 5.99825, (0.1, 30.0),
              "time constant of the coil current: the torque motor's inductance over the coil and amplifier's "
              "resistance, or a voltage-drive amplifier's own roll-off (assumed range: a current-drive amplifier "
              "gives well under 1 ms, a voltage drive into the coil several ms; Merritt sec. 5.8)",
              typical=(2.99912, 11.9965), si=1.0e-3, log_scale=True),
    )
    main_param = "T"
    # a delay and a slower spool also lag the flow more at higher frequency: fitted instead of the coil's lag,
    # they leave a residual of the wrong shape (a delay's phase grows linearly, the lag's saturates at 90 deg)
    mistaken_for = ("transport_delay", "valve_dynamics")
    states = (("i_coil", "mA", 0.0),)
    explanation = (
        "The torque motor is a coil: its current cannot follow the amplifier's command at once. With a "
        "current-drive amplifier the lag is a fraction of a millisecond; a voltage drive, a long cable or a "
        "current loop set slow leave a first-order lag T i_coil' = i - i_coil of some milliseconds ahead of "
        "the spool. The valve's flow then lags the command by the spool's own dynamics plus this lag, "
        "on the rig and on the flow bench alike."
    )
    signature = (
        "a phase lag of the valve flow behind the current growing as atan(2 pi f T) with frequency, gain "
        "falling past 1 / (2 pi T) Hz: seen on the valve bench's chirp (flow vs current) as well as in the "
        "loop; a transport delay or a slower spool fitted to it comes out different on slow and on fast "
        "excitation."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        corner = 1.0 / (2.0 * math.pi * params["T"] * 1e-3)
        return (f"the valve's coil current lags the command: a first-order lag of {params['T']:.3g} ms (corner "
                f"{corner:.3g} Hz), the torque motor's inductance against its drive")

    @staticmethod
    def state_rates(i, i_coil, T):
        return (i - i_coil) / T

    @staticmethod
    def coil_current(i_coil):
        return i_coil
