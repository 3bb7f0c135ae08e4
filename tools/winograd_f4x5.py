#!/usr/bin/env python3
"""Derive and check the Winograd F(4, 5) transforms the CPU convolution uses
(core/backends/cpu/cpu_conv_wino.h and cpu_conv.c's wino_g table).

Toom-Cook on the points 0, 1, -1, 2, -2, 1/2, -1/2 and infinity (the points of
the common F(6, 3)), transposed for correlation (Lavin & Gray 2016):

    y = At [(G g) * (Bt d)]        y: 4 outputs, g: 5 taps, d: 8 inputs

in exact rational arithmetic (fractions), so the identity is checked
exactly, not to rounding. The rows of Bt are then scaled (and G's rows by
the inverse) so that Bt holds small dyadic numbers (1, 1/2, 1/4, 5/4, 17/4,
21/4, ...: exact in binary floating point, and the pairs of rows for +p and
-p share their even and odd halves, which the C transform uses). Scaling
G's rows and At's columns by further powers of two changes no rounding
(checked with the fp32 error estimate below), so none is applied.

Run: python3 tools/winograd_f4x5.py   (prints the matrices and the C table of G;
with numpy available also the fp32 error of one 48-channel output against
float64).
"""
from fractions import Fraction as F
import random

PTS = [F(0), F(1), F(-1), F(2), F(-2), F(1, 2), F(-1, 2)]  # and infinity
M, R = 4, 5
N = M + R - 1


def evaluation(deg):
    """Rows: a polynomial of `deg` coefficients evaluated at each point, then
    its top coefficient (the point at infinity)."""
    rows = [[p ** i for i in range(deg)] for p in PTS]
    rows.append([F(int(i == deg - 1)) for i in range(deg)])
    return rows


def inverse(a):
    n = len(a)
    t = [row[:] + [F(int(i == j)) for j in range(n)] for i, row in enumerate(a)]
    for c in range(n):
        p = next(i for i in range(c, n) if t[i][c] != 0)
        t[c], t[p] = t[p], t[c]
        t[c] = [x / t[c][c] for x in t[c]]
        for i in range(n):
            if i != c and t[i][c] != 0:
                f = t[i][c]
                t[i] = [x - f * y for x, y in zip(t[i], t[c])]
    return [row[n:] for row in t]


def transforms():
    # linear convolution c = g * h: c = Ac [(G g) * (Bc h)]; its transpose is
    # the correlation: y = Bc^T [(G g) * (Ac^T d)]
    G = evaluation(R)
    Bc = evaluation(M)
    Ac = inverse(evaluation(N))
    At = [[Bc[j][i] for j in range(N)] for i in range(M)]
    Bt = [[Ac[j][i] for j in range(N)] for i in range(N)]
    # row scales making Bt dyadic, with the sign that makes the row of -p
    # (even half) - (odd half)
    D = [F(1), F(-9, 2), F(-9, 2), F(180), F(180), F(45, 64), F(45, 64), F(1)]
    Bt = [[D[i] * x for x in Bt[i]] for i in range(N)]
    G = [[x / D[i] for x in G[i]] for i in range(N)]
    return Bt, G, At


def check(Bt, G, At, trials=200):
    for _ in range(trials):
        g = [F(random.randint(-99, 99), random.randint(1, 9)) for _ in range(R)]
        d = [F(random.randint(-99, 99), random.randint(1, 9)) for _ in range(N)]
        u = [sum(G[i][k] * g[k] for k in range(R)) for i in range(N)]
        v = [sum(Bt[i][k] * d[k] for k in range(N)) for i in range(N)]
        y = [sum(At[i][k] * u[k] * v[k] for k in range(N)) for i in range(M)]
        assert y == [sum(g[k] * d[i + k] for k in range(R)) for i in range(M)]


def fp32_error(Bt, G, At, cin=48, trials=100):
    import numpy as np
    f32 = np.float32
    g_ = np.array([[float(x) for x in r] for r in G], dtype=f32)
    b_ = np.array([[float(x) for x in r] for r in Bt], dtype=f32)
    a_ = np.array([[float(x) for x in r] for r in At], dtype=f32)
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(trials):
        d = rng.standard_normal((cin, N, N)).astype(f32)
        w = (rng.standard_normal((cin, R, R)) / np.sqrt(cin * 25)).astype(f32)
        u = np.einsum("ik,ckl,jl->cij", g_, w, g_).astype(f32)
        v = np.einsum("ik,ckl,jl->cij", b_, d, b_).astype(f32)
        y = (a_ @ (u * v).sum(0).astype(f32) @ a_.T).astype(f32)
        ref = np.array([[(w.astype(np.float64) * d[:, i:i + R, j:j + R]).sum() for j in range(M)] for i in range(M)])
        worst = max(worst, float(np.abs(y - ref).max() / np.sqrt((ref ** 2).mean())))
    return worst


def main():
    Bt, G, At = transforms()
    check(Bt, G, At)
    print("exact identity checked")
    for name, m in (("Bt", Bt), ("G", G), ("At", At)):
        print(name)
        for row in m:
            print("   " + " ".join("%7s" % x for x in row))
    print("C table of G (cpu_conv.c wino_g):")
    for row in G:
        print("    {" + ", ".join("%s.0 / %s.0" % (x.numerator, x.denominator) for x in row) + "},")
    try:
        print("fp32, 48 input channels: worst |error| / rms(output) = %.2e" % fp32_error(Bt, G, At))
    except ImportError:
        pass


if __name__ == "__main__":
    main()
