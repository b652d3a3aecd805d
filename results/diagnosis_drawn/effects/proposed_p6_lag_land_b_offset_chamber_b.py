"""proposed_p6_lag_land_b_offset_chamber_b: a term proposed by ehas diagnose for /tmp/s1/work/p6_lag@land_b+offset@chamber_b/campaign.

i_valve [mA] += c_sgn·tanh(i / 0.05 mA)   with c_sgn = -0.02973 mA (95 % CI -0.03708 to -0.02238)

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
        Param("i_sgn", "mA", 0.0297314, (0.0, 0.594627),
              "a step of the current at null: c tanh(i / 0.05 mA) (a dead band when c < 0) (fitted: -0.02973, 95 % CI -0.03708 to -0.02238)", typical=(0.0148657, 0.0594627)),
    )
    main_param = "i_sgn"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_sgn·tanh(i / 0.05 mA) with c_sgn = -0.02973 mA (95 % CI -0.03708 to -0.02238)'
    signature = 'the residual it was fitted to: tanh(i / 0.05 mA)'

    @staticmethod
    def valve_current(i, i_sgn):
        return i + -(i_sgn * math.tanh(i / 0.05))
