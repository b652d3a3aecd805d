"""proposed_d23_volume_chamber_b: dead volume of each chamber (hoses, ports, manifolds), found by ehas diagnose on /tmp/drX_work/d23_volume@chamber_b/campaign.

The dead volumes are 22.3 cm^3 on chamber A's side and 38 cm^3 on chamber B's (the baseline: 20 each).
dV_a = 2.317 cm^3 (95 % CI -4.926 to 9.559)
dV_b = 18 cm^3 (95 % CI 5.434 to 30.57)
Residual against what does not repeat: 3.68x -> 1.5x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD23VolumeChamberB(Effect):
    name = "proposed_d23_volume_chamber_b"
    title = "dead volume of each chamber (hoses, ports, manifolds)"
    params = (
        Param("dV_a", "cm^3", 2.3166, (-18.0, 500.0),
              "oil volume added to chamber A's side beyond the baseline's 20 cm^3 (a longer hose, a manifold, an "
              "accumulator; assumed range: down to 2 cm^3 left, up to half a litre)", typical=(1.1583, 4.63319),
              si=1.0e-6),
        Param("dV_b", "cm^3", 18, (-18.0, 500.0),
              "oil volume added to chamber B's side beyond the baseline's 20 cm^3", typical=(9, 36),
              si=1.0e-6),
    )
    main_param = "dV_a"
    explanation = (
        "The baseline puts 20 cm^3 of hose and port volume on each side. A rig plumbed differently (a valve on "
        "a manifold far from the cylinder, long hoses on one side) has more oil under compression on one or "
        "both sides: chamber X's pressure rate is beta / (V_X + dV_X) times its net inflow. The hydraulic spring "
        "is softer, and unequally so on the two sides."
    )
    signature = (
        "pressure residuals that lag the model's where the chamber fills or drains fast (largest on fast "
        "runs), different between A and B; a lower hydraulic resonance; a constant bulk modulus fitted to it "
        "stands in for both sides at once."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"the dead volumes are {20.0 + params['dV_a']:.3g} cm^3 on chamber A's side and "
                f"{20.0 + params['dV_b']:.3g} cm^3 on chamber B's (the baseline: 20 each)")

    @staticmethod
    def chamber_flows(x, q_a, q_b, v, area, half_stroke, dead_volume, dV_a, dV_b):
        va = area * (half_stroke + x) + dead_volume
        vb = area * (half_stroke - x) + dead_volume
        # the rate scaled by V / (V + dV): an extra inflow of -(net inflow) dV / (V + dV)
        return (-(q_a - area * v) * dV_a / (va + dV_a), -(q_b + area * v) * dV_b / (vb + dV_b))
