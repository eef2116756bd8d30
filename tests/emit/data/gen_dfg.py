#!/usr/bin/env python3
"""Generates tests/emit/data/dfg_16x16.json, the small split-sum DFG table of the emit tests.

Definition (Karis 2013, UE4 IntegrateBRDF): for perceptual roughness r (alpha = r^2) and
NoV, A = E[(1 - Fc) * G_vis], B = E[Fc * G_vis] over GGX-importance-sampled half vectors,
with Fc = (1 - VoH)^5, G_vis = G * VoH / (NoH * NoV), and G the separable Smith-Schlick
term with k = alpha / 2. Hammersley points, 512 samples per entry. Grid: NoV = (i + 0.5)/16,
r = j / 15 (i, j in 0..15). Pure Python, deterministic; run from any directory.
"""
import json
import math
import os

N_SAMPLES = 512
GRID = 16


def radical_inverse(i):
    b = 0
    f = 0.5
    while i:
        if i & 1:
            b += f
        i >>= 1
        f *= 0.5
    return b


def dfg(nov, r):
    a = r * r
    k = a / 2.0
    v = (math.sqrt(1.0 - nov * nov), 0.0, nov)
    sa = sb = 0.0
    for i in range(N_SAMPLES):
        x1 = i / N_SAMPLES
        x2 = radical_inverse(i)
        phi = 2.0 * math.pi * x1
        cos_t = math.sqrt((1.0 - x2) / (1.0 + (a * a - 1.0) * x2))
        sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
        h = (sin_t * math.cos(phi), sin_t * math.sin(phi), cos_t)
        voh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2]
        l_z = 2.0 * voh * h[2] - v[2]
        nol = min(max(l_z, 0.0), 1.0)
        noh = min(max(h[2], 0.0), 1.0)
        voh = min(max(voh, 0.0), 1.0)
        if nol > 0.0:
            g = (nov / (nov * (1 - k) + k)) * (nol / (nol * (1 - k) + k))
            g_vis = g * voh / (noh * nov)
            fc = (1.0 - voh) ** 5
            sa += (1.0 - fc) * g_vis
            sb += fc * g_vis
    return sa / N_SAMPLES, sb / N_SAMPLES


def main():
    cols = {"NoV": [], "r": [], "A": [], "B": []}
    for i in range(GRID):
        nov = (i + 0.5) / GRID
        for j in range(GRID):
            r = j / (GRID - 1)
            a, b = dfg(nov, r)
            cols["NoV"].append(nov)
            cols["r"].append(r)
            cols["A"].append(round(a, 9))
            cols["B"].append(round(b, 9))
    table = {
        "format": "lgp-table/1",
        "inputs": ["NoV", "r"],
        "outputs": ["A", "B"],
        "columns": cols,
        "meta": {
            "name": "dfg_16x16 (split-sum DFG, UE4 IntegrateBRDF)",
            "generated_by": "tests/emit/data/gen_dfg.py (generated file; do not edit)",
            "definition": "A = E[(1-Fc) G_vis], B = E[Fc G_vis], GGX alpha = r^2, "
                          "Smith-Schlick k = alpha/2, Fc = (1-VoH)^5",
            "grid": {"NoV": "(i+0.5)/16, i=0..15", "r": "j/15, j=0..15"},
            "integrator": "Hammersley importance sampling of the GGX half vector",
            "samples": N_SAMPLES,
            "error": "quasi Monte Carlo; about 1e-3 absolute",
        },
    }
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "dfg_16x16.json")
    with open(out, "w") as f:
        json.dump(table, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
