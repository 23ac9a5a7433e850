"""Reference albedos of a unit cosine lobe max(0, a.v)^n whose axis a is at polar angle
theta_a: I = int_0^1 x^n ring(x) dx, with ring(x) the closed-form azimuthal integral of
max(0, v_z) over the ring at cos(alpha) = x, computed by mpmath at 30 digits."""
import mpmath as mp

mp.mp.dps = 30


def ring(x, c):
    a = x * c
    b = mp.sqrt((1 - x * x) * (1 - c * c))
    if a >= b:
        return 2 * mp.pi * a
    if a <= -b:
        return 0
    return 2 * (a * mp.acos(-a / b) + mp.sqrt(b * b - a * a))


for n, deg in [(0.5, 10), (18.6, 80), (63.8, 89), (1000, 60), (1000, 89.5)]:
    c = mp.cos(mp.radians(deg))
    k = mp.sqrt(1 - c * c)
    print(n, deg, mp.quad(lambda x: x ** n * ring(x, c), [0, k, 1]))
