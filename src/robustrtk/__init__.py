"""robustrtk: robust high-precision positioning for hostile signal environments.

Pseudolite rooms, urban canyons and smartphones: double-differenced code and carrier-phase
positioning with EKF/UKF/robust UKF, LAMBDA and partial ambiguity resolution.
"""

__version__ = "0.1.0"
