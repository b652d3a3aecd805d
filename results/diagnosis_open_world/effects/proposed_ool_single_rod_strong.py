"""proposed_ool_single_rod_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_single_rod_strong/campaign.

(Q_A, Q_B) [m^3/s] += c_gb·(0, q_B)   with c_gb = 0.333 - (95 % CI 0.3323 to 0.3336)
F_piston [N] += c_pa·p_A   with c_pa = 0.0002488 m^2 (95 % CI 0.000243 to 0.0002545)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 407 -> 38.5; fit 22.8 % -> 80.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolSingleRodStrong(Effect):
    name = "proposed_ool_single_rod_strong"
    title = "proposed term (chamber flows, piston force)"
    params = (
        Param("q_gb", "-", 0.332961, (0.0, 6.65923),
              "extra flow gain into or out of chamber B (relative) (fitted: 0.333, 95 % CI 0.3323 to 0.3336)", typical=(0.166481, 0.665923)),
        Param("f_pa", "m^2", 0.000248754, (0.0, 0.00497508),
              "force per Pa of chamber A pressure (area error on side A) (fitted: 0.0002488, 95 % CI 0.000243 to 0.0002545)", typical=(0.000124377, 0.000497508)),
    )
    main_param = "q_gb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_gb·(0, q_B) with c_gb = 0.333 - (95 % CI 0.3323 to 0.3336); F_piston [N] += c_pa·p_A with c_pa = 0.0002488 m^2 (95 % CI 0.000243 to 0.0002545)'
    signature = 'the residual it was fitted to: (0, q_B), p_A'

    @staticmethod
    def chamber_flows(q_b, q_gb):
        dqa = 0.0
        dqb = 0.0
        dqb += q_gb * q_b
        return dqa, dqb

    @staticmethod
    def piston_force(pa, f_pa):
        return (f_pa * pa)
