"""proposed_d01_volume_supply: a term proposed by ehas diagnose for /tmp/drB_work/d01_volume@supply/campaign.

(Q_A, Q_B) [m^3/s] += c_rsup·the inflow land's flow times -|q_S| / (2 (p_S - p_in)): supply drop per supply flow   with c_rsup = 3.4e+09 Pa s/m^3 (95 % CI 3.388e+09 to 3.412e+09)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.75 -> 1.29; fit 91.7 % -> 97.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD01VolumeSupply(Effect):
    name = "proposed_d01_volume_supply"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_rsup", "Pa s/m^3", 3.39986e+09, (0.0, 6.79973e+10),
              "resistance of the supply line: supply pressure drop per supply flow (fitted: 3.4e+09, 95 % CI 3.388e+09 to 3.412e+09)", typical=(1.69993e+09, 6.79973e+09)),
    )
    main_param = "q_rsup"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_rsup·the inflow land's flow times -|q_S| / (2 (p_S - p_in)): supply drop per supply flow with c_rsup = 3.4e+09 Pa s/m^3 (95 % CI 3.388e+09 to 3.412e+09)"
    signature = "the residual it was fitted to: the inflow land's flow times -|q_S| / (2 (p_S - p_in)): supply drop per supply flow"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_rsup):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqa -= q_rsup * abs(q_supply) * q_a / (2.0 * max(ps - pa, 1.0e5))
        else:
            dqb -= q_rsup * abs(q_supply) * q_b / (2.0 * max(ps - pb, 1.0e5))
        return dqa, dqb
