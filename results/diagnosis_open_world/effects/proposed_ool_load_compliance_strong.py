"""proposed_ool_load_compliance_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_load_compliance_strong/campaign.

(Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B))   with c_int = 4.087e-13 m^3/s/Pa (95 % CI 2.246e-13 to 5.927e-13)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 66.9 -> 66.5; fit 63.0 % -> 63.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLoadComplianceStrong(Effect):
    name = "proposed_ool_load_compliance_strong"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_int", "m^3/s/Pa", 4.08674e-13, (0.0, 8.17349e-12),
              "leakage across the piston, per Pa of load pressure (fitted: 4.087e-13, 95 % CI 2.246e-13 to 5.927e-13)", typical=(2.04337e-13, 8.17349e-13)),
    )
    main_param = "q_int"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B)) with c_int = 4.087e-13 m^3/s/Pa (95 % CI 2.246e-13 to 5.927e-13)'
    signature = 'the residual it was fitted to: (-(p_A - p_B), +(p_A - p_B))'

    @staticmethod
    def chamber_flows(pa, pb, q_int):
        dqa = 0.0
        dqb = 0.0
        dqa -= q_int * (pa - pb)
        dqb += q_int * (pa - pb)
        return dqa, dqb
