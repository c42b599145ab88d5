"""Robot arms (URDF as data), wrist force/torque sensors and the two-arm cable scene."""
