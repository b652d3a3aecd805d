"""proposed_p6_lag_land_b_offset_chamber_b: a term proposed by ehas diagnose for /work/runs/drawn/p6_lag@land_b+offset@chamber_b/campaign.

i_valve [mA] += c_sgn·tanh(i / 0.05 mA)   with c_sgn = -0.02984 mA (95 % CI -0.0372 to -0.02249)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 92.1 -> 81.2; fit 77.4 % -> 77.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedP6LagLandBOffsetChamberB(Effect):
    name = "proposed_p6_lag_land_b_offset_chamber_b"
    title = "proposed term (valve current)"
    params = (
        Param("i_sgn", "mA", 0.0298443, (0.0, 0.596886),
              "current per - of a step at null of the valve current, the valve's current (fitted: -0.02984, 95 % CI -0.0372 to -0.02249)", typical=(0.0149221, 0.0596886)),
    )
    main_param = "i_sgn"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_sgn·tanh(i / 0.05 mA) with c_sgn = -0.02984 mA (95 % CI -0.0372 to -0.02249)'
    signature = 'the residual it was fitted to: tanh(i / 0.05 mA)'

    @staticmethod
    def valve_current(i, i_sgn):
        return i + -(i_sgn * math.tanh(i / 0.05))
