"""proposed_d06_volume_chamber_b: pressure loss in the supply line between the regulated supply and the valve, found by ehas diagnose on /tmp/drLH_work/d06_volume@chamber_b/campaign.

The supply line loses 23.9 bar at 25 LPM before the valve (growing with the square of the flow).
dp_25 = 23.91 bar (95 % CI 23.51 to 24.32)
Residual against what does not repeat: 3.69x -> 2.3x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedD06VolumeChamberB(Effect):
    name = "proposed_d06_volume_chamber_b"
    title = "pressure loss in the supply line between the regulated supply and the valve"
    valve_side = True  # flow through the metering lands: a meter in line A (and the bench's) reads it
    params = (
        Param("dp_25", "bar", 23.9083, (0.0, 150.0),
              "pressure lost between the supply's gauge and the valve's pressure port at 25 LPM (a long or thin "
              "hose, a filter, a check valve; assumed range: up to the supply itself)",
              typical=(11.9541, 47.8166), log_scale=True, si=1.0e5),
    )
    main_param = "dp_25"
    explanation = (
        "The supply pressure is regulated (and logged) at the pump or accumulator, but the valve's pressure "
        "port sits behind a hose and a filter that drop dp = dp_25 (Q / 25 LPM)^2 at the flow Q they carry. "
        "The metering land feeding the pressurised chamber sees P_S - dp: the valve gives less flow when it "
        "gives much, and the logged supply stays flat."
    )
    signature = (
        "flow and speed below the model's at large openings only (a saturation-like shortfall growing with "
        "the square of the flow); the supply pressure residual is flat; current residual in the fast parts of "
        "the large, fast runs."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the supply line loses {params['dp_25']:.3g} bar at 25 LPM before the valve (growing with the "
                f"square of the flow)")

    @staticmethod
    def chamber_flows(qc, pa, pb, ps, rated_drop, dp_25):
        # the feeding land passes q = |qc| sqrt((ps - dp_25 (q / 25 LPM)^2 - p_in) / half): solved for q,
        # q = q0 / sqrt(1 + dp_25 qc^2 / (half q25^2)) with q0 the baseline's flow
        half = 0.5 * rated_drop
        q25 = 25.0e-3 / 60.0
        p_in = pa if qc >= 0.0 else pb
        d0 = ps - p_in
        if d0 <= 0.0:
            return 0.0, 0.0
        q0 = abs(qc) * math.sqrt(d0 / half)
        dq = q0 * (1.0 / math.sqrt(1.0 + dp_25 * qc * qc / (half * q25 * q25)) - 1.0)
        if qc >= 0.0:
            return dq, 0.0
        return 0.0, dq
