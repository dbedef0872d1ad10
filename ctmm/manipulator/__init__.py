"""Controlled flexible manipulator: PD hub torque and PZT modal-velocity feedback."""
