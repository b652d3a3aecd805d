"""proposed_p6_lag_land_b_offset_chamber_b: a term proposed by ehas diagnose for /tmp/drawnAw/p6_lag@land_b+offset@chamber_b/campaign.

(Q_A, Q_B) [m^3/s] += c_ext·(-p_A, -p_B)   with c_ext = -1.921e-13 m^3/s/Pa (95 % CI -2.249e-13 to -1.593e-13)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 620 -> 520; fit 28.9 % -> 47.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP6LagLandBOffsetChamberB(Effect):
    name = "proposed_p6_lag_land_b_offset_chamber_b"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_ext", "m^3/s/Pa", 1.92098e-13, (0.0, 3.84196e-12),
              "leakage from each chamber to drain, per Pa (fitted: -1.921e-13, 95 % CI -2.249e-13 to -1.593e-13)", typical=(9.60489e-14, 3.84196e-13)),
    )
    main_param = "q_ext"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_ext·(-p_A, -p_B) with c_ext = -1.921e-13 m^3/s/Pa (95 % CI -2.249e-13 to -1.593e-13)'
    signature = 'the residual it was fitted to: (-p_A, -p_B)'

    @staticmethod
    def chamber_flows(pa, pb, q_ext):
        dqa = 0.0
        dqb = 0.0
        dqa -= (-q_ext) * pa
        dqb -= (-q_ext) * pb
        return dqa, dqb
