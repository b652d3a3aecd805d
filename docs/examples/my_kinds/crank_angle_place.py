"""A place of my own: the crank's torque balance with the crank's angle (an end stop, a spring that meets a gap),
every built-in kind of static term put there."""
import math

from ehas_env.physics.balance_blocks import BALANCE_KINDS, BalancePlace

CRANK_ANGLE = BalancePlace("crank_torque", "crank_angle", "theta", "rad", 0.5, (180.0 / math.pi, "deg"), "N m",
                           250.0, (1.0, "N m"), "t", "the crank torque balance", "the crank angle")
TERMS = [kind.at(CRANK_ANGLE) for kind in BALANCE_KINDS if kind.fits(CRANK_ANGLE)]
