"""Independent reference values for the blue-paint model of Lafortune et al. 1997,
Table 1 (550 nm), evaluated with mpmath at 30 digits straight from Eq. 8:

    f_r(u, v) = sum_i max(0, Cx ux vx + Cy uy vy + Cz uz vz)^n_i + f_d

with f_d = 0.13 /sr (Table 1's "Diffuse" row; rho = 0.13 pi). Run with
`python3 table1.py`; the numbers are asserted in tests/it/closed_forms.rs (values) and
tests/it/albedo.rs (albedo).
"""
import mpmath as mp

mp.mp.dps = 30
LOBES = [(mp.mpf("0.86"), mp.mpf("0.77"), mp.mpf("18.6")),
         (mp.mpf("-0.41"), mp.mpf("0.018"), mp.mpf("2.58")),
         (mp.mpf("-1.03"), mp.mpf("0.70"), mp.mpf("63.8"))]
FD = mp.mpf("0.13")


def d(theta, phi):
    t, p = mp.radians(theta), mp.radians(phi)
    return (mp.sin(t) * mp.cos(p), mp.sin(t) * mp.sin(p), mp.cos(t))


def f(wi, wo):
    u, v = d(*wi), d(*wo)
    s = FD
    for cxy, cz, n in LOBES:
        dot = cxy * u[0] * v[0] + cxy * u[1] * v[1] + cz * u[2] * v[2]
        if dot > 0:
            s += dot ** n
    return s


CASES = [((0, 0), (0, 0)), ((35, 0), (35, 180)), ((65, 0), (65, 0)),
         ((65, 0), (80, 180)), ((30, 45), (50, 200)), ((70, 0), (60, 180))]
for wi, wo in CASES:
    print(wi, wo, mp.nstr(f(wi, wo), 20))


def albedo(theta_i):
    """rho(theta_i) = int f cos(theta_o) d(omega_o), phi_i = 0, by mpmath's
    tanh-sinh quadrature in (cos theta_o, phi_o), split where the lobes peak."""
    mp.mp.dps = 20
    u = d(theta_i, 0)

    def g(z, p):
        s = mp.sqrt(1 - z * z)
        v = (s * mp.cos(p), s * mp.sin(p), z)
        tot = FD
        for cxy, cz, n in LOBES:
            dot = cxy * u[0] * v[0] + cxy * u[1] * v[1] + cz * u[2] * v[2]
            if dot > 0:
                tot += dot ** n
        return tot * z

    zs = sorted(set([0, 0.5, 0.8, 0.9, 0.95, 0.99, 1] + [mp.cos(mp.radians(theta_i))]))
    ps = [0, mp.pi / 8, mp.pi / 2, mp.pi, 3 * mp.pi / 2, 15 * mp.pi / 8, 2 * mp.pi]
    return mp.quad(g, zs, ps)


if __name__ == "__main__":
    for t in (0, 30, 60, 85):
        print("albedo", t, mp.nstr(albedo(t), 12))
