"""proposed_unl_pair_land_flow_forces_end_cushion: a term proposed by ehas diagnose for /work/runs/unl/unl_pair_land_flow_forces+end_cushion/campaign.

(Q_A, Q_B) [m^3/s] += c_lam·each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop   with c_lam = -0.04932 - (95 % CI -0.05729 to -0.04134)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.8 -> 2.33; fit 94.7 % -> 94.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairLandFlowForcesEndCushion(Effect):
    name = "proposed_unl_pair_land_flow_forces_end_cushion"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_lam", "-", 0.0493169, (0.0, 0.986339),
              "share of the land flow that goes with the land's drop itself, not its square root (laminar metering; relative, at the rated drop p_S / 2) (fitted: -0.04932, 95 % CI -0.05729 to -0.04134)", typical=(0.0246585, 0.0986339)),
    )
    main_param = "q_lam"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_lam·each land's flow times (sqrt(drop / (p_S / 2)) - 1): metering that goes with the drop with c_lam = -0.04932 - (95 % CI -0.05729 to -0.04134)"
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
