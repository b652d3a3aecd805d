"""proposed_pair_single_rod_disc_drag: chamber B's piston area differs from chamber A's, found by ehas diagnose on /tmp/ow/work/pair_single_rod+disc_drag/campaign.

Chamber B's piston area is 0.90 of chamber A's.
d_area = 0.09975 - (95 % CI 0.09966 to 0.09984)
Residual against what does not repeat: 75.6x -> 1.08x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedPairSingleRodDiscDrag(Effect):
    name = "proposed_pair_single_rod_disc_drag"
    title = "chamber B's piston area differs from chamber A's"
    params = (
        Param("d_area", "-", 0.0997492, (-0.6, 0.7),
              "1 - A_B / A_A: the share of the piston area the rod (or a different bore) takes on the B side "
              "(assumed range: a rod up to 0.7 of the bore's area; negative: B larger)",
              typical=(0.0498746, 0.199498)),
    )
    main_param = "d_area"
    explanation = (
        "The baseline's actuator is double-rod, equal areas A on both sides. A single-rod actuator (or a "
        "rig whose B-side area differs) has A_B = (1 - d_area) A: the piston force is A P_A - A_B P_B and "
        "chamber B's volume changes by A_B x' instead of A x'. (Chamber B's volume at mid-stroke is kept: "
        "its change is second order.)"
    )
    signature = (
        "load residual proportional to P_B; pressure residuals that differ between extending and retracting "
        "(B's pressure follows velocity with a different gain than A's); a velocity-dependent offset of the "
        "load pressure the controller holds."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return f"chamber B's piston area is {1.0 - params['d_area']:.2f} of chamber A's"

    @staticmethod
    def piston_force(pb, area, d_area):
        return d_area * area * pb

    @staticmethod
    def chamber_flows(v, area, d_area):
        return 0.0, -d_area * area * v
