"""proposed_ool_lugre_friction_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_lugre_friction_strong/campaign.

(Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B))   with c_int = 3.982e-14 m^3/s/Pa (95 % CI 1.89e-14 to 6.073e-14)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.27 -> 4.23; fit 86.9 % -> 86.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLugreFrictionStrong(Effect):
    name = "proposed_ool_lugre_friction_strong"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_int", "m^3/s/Pa", 3.9815e-14, (0.0, 7.963e-13),
              "leakage across the piston, per Pa of load pressure (fitted: 3.982e-14, 95 % CI 1.89e-14 to 6.073e-14)", typical=(1.99075e-14, 7.963e-14)),
    )
    main_param = "q_int"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B)) with c_int = 3.982e-14 m^3/s/Pa (95 % CI 1.89e-14 to 6.073e-14)'
    signature = 'the residual it was fitted to: (-(p_A - p_B), +(p_A - p_B))'

    @staticmethod
    def chamber_flows(pa, pb, q_int):
        dqa = 0.0
        dqb = 0.0
        dqa -= q_int * (pa - pb)
        dqb += q_int * (pa - pb)
        return dqa, dqb
