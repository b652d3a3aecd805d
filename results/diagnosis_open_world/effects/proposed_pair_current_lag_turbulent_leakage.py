"""proposed_pair_current_lag_turbulent_leakage: a term proposed by ehas diagnose for /tmp/ow2/work/pair_current_lag+turbulent_leakage/campaign.

(Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B))   with c_int = 7.998e-13 m^3/s/Pa (95 % CI 6.645e-13 to 9.352e-13)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 8.74 -> 5.34; fit 93.4 % -> 94.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedPairCurrentLagTurbulentLeakage(Effect):
    name = "proposed_pair_current_lag_turbulent_leakage"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_int", "m^3/s/Pa", 7.99847e-13, (0.0, 1.59969e-11),
              "leakage across the piston, per Pa of load pressure (fitted: 7.998e-13, 95 % CI 6.645e-13 to 9.352e-13)", typical=(3.99923e-13, 1.59969e-12)),
    )
    main_param = "q_int"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_int·(-(p_A - p_B), +(p_A - p_B)) with c_int = 7.998e-13 m^3/s/Pa (95 % CI 6.645e-13 to 9.352e-13)'
    signature = 'the residual it was fitted to: (-(p_A - p_B), +(p_A - p_B))'

    @staticmethod
    def chamber_flows(pa, pb, q_int):
        dqa = 0.0
        dqb = 0.0
        dqa -= q_int * (pa - pb)
        dqb += q_int * (pa - pb)
        return dqa, dqb
