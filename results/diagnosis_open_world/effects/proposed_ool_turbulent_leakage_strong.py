"""proposed_ool_turbulent_leakage_strong: a term proposed by ehas diagnose for /tmp/ow_final_work/ool_turbulent_leakage_strong/campaign.

(Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B))   with c_int = 2.821e-12 m^3/s/Pa (95 % CI 2.701e-12 to 2.941e-12)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 28.2 -> 10.5; fit 87.8 % -> 92.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolTurbulentLeakageStrong(Effect):
    name = "proposed_ool_turbulent_leakage_strong"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_int", "m^3/s/Pa", 2.82131e-12, (0.0, 5.64262e-11),
              "leakage across the piston, per Pa of load pressure (fitted: 2.821e-12, 95 % CI 2.701e-12 to 2.941e-12)", typical=(1.41066e-12, 5.64262e-12)),
    )
    main_param = "q_int"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B)) with c_int = 2.821e-12 m^3/s/Pa (95 % CI 2.701e-12 to 2.941e-12)'
    signature = 'the residual it was fitted to: (-(p_A - p_B), +(p_A - p_B))'

    @staticmethod
    def chamber_flows(pa, pb, q_int):
        dqa = 0.0
        dqb = 0.0
        dqa -= q_int * (pa - pb)
        dqb += q_int * (pa - pb)
        return dqa, dqb
