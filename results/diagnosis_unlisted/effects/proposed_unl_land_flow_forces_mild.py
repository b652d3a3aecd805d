"""proposed_unl_land_flow_forces_mild: a term proposed by ehas diagnose for /work/runs/unl/unl_land_flow_forces_mild/campaign.

(Q_A, Q_B) [m^3/s] += c_lam·each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop   with c_lam = -0.04017 - (95 % CI -0.04155 to -0.03878)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.57 -> 1.22; fit 96.3 % -> 97.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlLandFlowForcesMild(Effect):
    name = "proposed_unl_land_flow_forces_mild"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_lam", "-", 0.0401679, (0.0, 0.803358),
              "share of the land flow that goes with the land's drop itself, not its square root (laminar metering; relative, at the rated drop p_S / 2) (fitted: -0.04017, 95 % CI -0.04155 to -0.03878)", typical=(0.0200839, 0.0803358)),
    )
    main_param = "q_lam"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_lam·each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop with c_lam = -0.04017 - (95 % CI -0.04155 to -0.03878)"
    signature = "the residual it was fitted to: each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_lam):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqa += (-q_lam) * q_a * (math.sqrt(max(ps - pa, 1.0e5) / (0.5 * max(ps, 1.0e5))) - 1.0)
            dqb += (-q_lam) * q_b * (math.sqrt(max(pb, 1.0e5) / (0.5 * max(ps, 1.0e5))) - 1.0)
        else:
            dqb += (-q_lam) * q_b * (math.sqrt(max(ps - pb, 1.0e5) / (0.5 * max(ps, 1.0e5))) - 1.0)
            dqa += (-q_lam) * q_a * (math.sqrt(max(pa, 1.0e5) / (0.5 * max(ps, 1.0e5))) - 1.0)
        return dqa, dqb
