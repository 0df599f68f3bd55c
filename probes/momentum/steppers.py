from mom import *
from rrrobot_gym.integrators.rk4 import unit_quaternion

def rk4_momentum(f, g, t, y, h, n, tg, sim):
    k, layout = dynamics.constants(sim.robot, sim.model), dynamics.leg_layout(sim.robot)
    def F(t, z):
        p = z[8:11]
        c = swap(z, omega_of(z, k, layout))
        dc = f(t, c)
        return swap(dc, p_rate(c, p, k, layout))
    z = swap(y, p_of(y, k, layout))
    half, sixth = 0.5 * h, h / 6.0
    for _ in range(n):
        k1 = F(t, z)
        k2 = F(t + half, [a + half * b for a, b in zip(z, k1)])
        k3 = F(t + half, [a + half * b for a, b in zip(z, k2)])
        k4 = F(t + h, [a + h * b for a, b in zip(z, k3)])
        z = [a + sixth * (b1 + 2.0 * (b2 + b3) + b4) for a, b1, b2, b3, b4 in zip(z, k1, k2, k3, k4)]
        unit_quaternion(z)
        t += h
    return swap(z, omega_of(z, k, layout))

if __name__ == "__main__":
    d = load()
    for n in (15, 18, 20, 30):
        t0 = time.time()
        report(f"momentum rk4 n={n}", d, run(d, rk4_momentum, n), t0)
