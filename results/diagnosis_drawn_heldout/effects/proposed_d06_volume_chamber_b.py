"""proposed_d06_volume_chamber_b: a term proposed by ehas diagnose for /tmp/drH_work/d06_volume@chamber_b/campaign.

(Q_A, Q_B) [m^3/s] += c_rline·each land's flow times -|q| / (2 drop): line resistance   with c_rline = 1.79e+09 Pa s/m^3 (95 % CI 1.58e+09 to 2e+09)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 61.7 -> 51.1; fit 69.7 % -> 69.9 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD06VolumeChamberB(Effect):
    name = "proposed_d06_volume_chamber_b"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_rline", "Pa s/m^3", 1.79015e+09, (0.0, 3.5803e+10),
              "resistance of the lines between valve and chambers: pressure drop per flow (fitted: 1.79e+09, 95 % CI 1.58e+09 to 2e+09)", typical=(8.95075e+08, 3.5803e+09)),
    )
    main_param = "q_rline"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_rline·each land's flow times -|q| / (2 drop): line resistance with c_rline = 1.79e+09 Pa s/m^3 (95 % CI 1.58e+09 to 2e+09)"
    signature = "the residual it was fitted to: each land's flow times -|q| / (2 drop): line resistance"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_rline):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqa -= q_rline * abs(q_a) * q_a / (2.0 * max(ps - pa, 1.0e5))
            dqb -= q_rline * abs(q_b) * q_b / (2.0 * max(pb, 1.0e5))
        else:
            dqb -= q_rline * abs(q_b) * q_b / (2.0 * max(ps - pb, 1.0e5))
            dqa -= q_rline * abs(q_a) * q_a / (2.0 * max(pa, 1.0e5))
        return dqa, dqb
