"""proposed_d17_offset_return: return-line (tank) pressure at the valve, found by ehas diagnose on /work/runs/drawn/d17_offset@return/campaign.

The return line is at 7.44 bar at the valve's return lands (the baseline: 0 bar).
p_t = 7.444 bar (95 % CI 7.424 to 7.464)
Residual against what does not repeat: 6.36x -> 1.14x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedD17OffsetReturn(Effect):
    name = "proposed_d17_offset_return"
    title = "return-line (tank) pressure at the valve"
    valve_side = True  # flow through the metering lands: a meter in line A (and the bench's) reads it
    params = (
        Param("p_t", "bar", 7.44412, (0.0, 60.0),
              "pressure in the return line at the valve's return lands (assumed: a filter, cooler or long "
              "return hose; the baseline takes 0)",
              typical=(3.72206, 14.8882), log_scale=True, si=1e5),
    )
    main_param = "p_t"
    explanation = (
        "The baseline drains the low-pressure chamber to 0 bar. With back pressure p_t in the return line the "
        "draining land sees P - p_t instead of P: the outflow is smaller, both chambers sit higher, and the "
        "load pressure available to move the crank is lower."
    )
    signature = (
        "both chamber pressures' residuals positive and largest in the draining chamber; mean chamber pressure "
        "higher than the model's; a current residual that follows the load and the sign of the velocity."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return f"the return line is at {params['p_t']:.3g} bar at the valve's return lands (the baseline: 0 bar)"

    @staticmethod
    def chamber_flows(qc, pa, pb, rated_drop, p_t):
        half = 0.5 * rated_drop
        if qc >= 0.0:  # B drains to the return line
            dq = -qc * (math.copysign(math.sqrt(abs(pb - p_t) / half), pb - p_t)
                        - math.copysign(math.sqrt(abs(pb) / half), pb))
            return 0.0, dq
        dq = qc * (math.copysign(math.sqrt(abs(pa - p_t) / half), pa - p_t)
                   - math.copysign(math.sqrt(abs(pa) / half), pa))
        return dq, 0.0
