def derivative_kernel(c, leg_torque, k, leg_accel=None, torque_out=None, contact_out=None):
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def contact_kernel(c, d, k):
    return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
