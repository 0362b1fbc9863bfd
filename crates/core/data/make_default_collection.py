#!/usr/bin/env python3
# SPDX-License-Identifier: MIT OR Apache-2.0
"""Generate brdf-basis's embedded default collection of Ashikhmin-Shirley materials.

Every number written to ``crates/core/data/default_collection.csv`` is computed here from the
physical inputs below (refractive indices, complex indices of metals, microfacet
roughness, diffuse reflectances). Nothing is copied from a measured or fitted BRDF
data set. Standard library only; the output is deterministic.

Usage (from the repository root):

    python3 crates/core/data/make_default_collection.py            # writes crates/core/data/default_collection.csv
    python3 crates/core/data/make_default_collection.py --table    # also prints the README's Markdown table
    python3 crates/core/data/make_default_collection.py --stdout   # prints the CSV instead of writing it

The model (SPEC section 1), per channel c:

    f_c = d_c / pi + s_c * rho_s(F0, n)
    rho_s = (n + 1) (N.H)^n F(F0, wo.H) / (8 pi (wo.H) max(N.wi, N.wo)),  Schlick F.

Rules applied here (see crates/core/data/README.md for the discussion):

* Dielectric:  F0 = ((eta - 1) / (eta + 1))^2 at 589.3 nm (sodium D line); white
  specular, s_r = s_g = s_b = S.
* Conductor:   R_c = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) at 650 / 550 / 450 nm for
  R / G / B (n, k linearly interpolated in wavelength between tabulated points);
  F0 = Rec. 709 luminance-weighted mean of R_rgb; s_c = S * R_c / F0 (so that
  s_c * F0 = S * R_c exactly at normal incidence).
* Metallic car paint: a single lobe from aluminium flakes under a tinted clear
  coat: F0 = F0(Al); s_c = S * T_c * R_Al,c / F0(Al) with T_c the pigment colour;
  d_c = (1 - flake coverage) * pigment colour.
* Exponent:    n = 2 / alpha^2 - 2 (Blinn-Phong <-> Beckmann correspondence,
  alpha = RMS microfacet slope).
* Diffuse:     d_c = linear-sRGB diffuse reflectance (specular excluded) of the body;
  0 for bare metals and clear transparent solids.
* sRGB -> linear (IEC 61966-2-1): c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055)^2.4.
"""

import math
import os
import sys

# ---------------------------------------------------------------------------
# Colour science constants
# ---------------------------------------------------------------------------

# Rec. ITU-R BT.709 / sRGB luminance weights (Y = 0.2126 R + 0.7152 G + 0.0722 B).
REC709 = (0.2126, 0.7152, 0.0722)

# Wavelengths (micrometres) that stand for the R, G, B channels of the conductors.
RGB_WAVELENGTHS_UM = (0.650, 0.550, 0.450)

# Wavelength (micrometres) at which dielectric indices are taken: sodium D line.
SODIUM_D_UM = 0.5893


def srgb_to_linear(c8):
    """8-bit sRGB component -> linear value in [0, 1] (IEC 61966-2-1 transfer function)."""
    c = c8 / 255.0
    if c <= 0.04045:
        return c / 12.92
    return ((c + 0.055) / 1.055) ** 2.4


def sellmeier1(b, c_um2, lam_um):
    """One-term Sellmeier formula n^2 - 1 = B lam^2 / (lam^2 - C) (refractiveindex.info 'formula 2')."""
    l2 = lam_um * lam_um
    return math.sqrt(1.0 + b * l2 / (l2 - c_um2))


# ---------------------------------------------------------------------------
# Conductors: tabulated complex refractive index n + ik.
# Rows are (wavelength in um, n, k), exactly as tabulated by the cited source
# (taken from the public-domain refractiveindex.info database, which reproduces
# the published tables); only the rows bracketing 450, 550 and 650 nm are kept.
# ---------------------------------------------------------------------------

METALS = {
    "Ag": {
        "label": "silver",
        "source": "Johnson & Christy 1972, Phys. Rev. B 6, 4370 (via refractiveindex.info)",
        "rows": [(0.4305, 0.04, 2.462), (0.4509, 0.04, 2.657),
                 (0.5486, 0.06, 3.586), (0.5821, 0.05, 3.858),
                 (0.6168, 0.06, 4.152), (0.6595, 0.05, 4.483)],
    },
    "Au": {
        "label": "gold",
        "source": "Johnson & Christy 1972, Phys. Rev. B 6, 4370 (via refractiveindex.info)",
        "rows": [(0.4305, 1.45, 1.948), (0.4509, 1.38, 1.914),
                 (0.5486, 0.43, 2.455), (0.5821, 0.29, 2.863),
                 (0.6168, 0.21, 3.272), (0.6595, 0.14, 3.697)],
    },
    "Cu": {
        "label": "copper",
        "source": "Johnson & Christy 1972, Phys. Rev. B 6, 4370 (via refractiveindex.info)",
        "rows": [(0.4305, 1.25, 2.305), (0.4509, 1.24, 2.397),
                 (0.5486, 1.02, 2.577), (0.5821, 0.70, 2.704),
                 (0.6168, 0.30, 3.205), (0.6595, 0.22, 3.747)],
    },
    "Al": {
        "label": "aluminium",
        "source": "Rakic 1995, Appl. Opt. 34, 4755 (via refractiveindex.info)",
        "rows": [(0.44280, 0.6079, 5.3676), (0.47687, 0.7278, 5.7781),
                 (0.51660, 0.8734, 6.2418), (0.56357, 1.0728, 6.7839),
                 (0.61993, 1.3660, 7.4052), (0.65225, 1.5724, 7.7354)],
    },
    "Cr": {
        "label": "chromium",
        "source": "Johnson & Christy 1974, Phys. Rev. B 9, 5056 (via refractiveindex.info)",
        "rows": [(0.431, 2.19, 3.04), (0.451, 2.33, 3.14),
                 (0.549, 3.18, 3.33), (0.582, 3.22, 3.30),
                 (0.617, 3.17, 3.30), (0.659, 3.09, 3.34)],
    },
    "Fe": {
        "label": "iron",
        "source": "Johnson & Christy 1974, Phys. Rev. B 9, 5056 (via refractiveindex.info)",
        "rows": [(0.431, 2.48, 2.71), (0.451, 2.59, 2.77),
                 (0.549, 2.95, 2.93), (0.582, 2.94, 2.99),
                 (0.617, 2.88, 3.05), (0.659, 2.92, 3.10)],
    },
    "Ni": {
        "label": "nickel",
        "source": "Johnson & Christy 1974, Phys. Rev. B 9, 5056 (via refractiveindex.info)",
        "rows": [(0.431, 1.71, 2.82), (0.451, 1.73, 2.95),
                 (0.549, 1.92, 3.61), (0.582, 1.96, 3.80),
                 (0.617, 1.99, 4.02), (0.659, 1.99, 4.26)],
    },
    "Ti": {
        "label": "titanium",
        "source": "Johnson & Christy 1974, Phys. Rev. B 9, 5056 (via refractiveindex.info)",
        "rows": [(0.431, 2.21, 3.01), (0.451, 2.27, 3.04),
                 (0.549, 2.54, 3.43), (0.582, 2.60, 3.58),
                 (0.617, 2.67, 3.72), (0.659, 2.76, 3.84)],
    },
    "Co": {
        "label": "cobalt",
        "source": "Johnson & Christy 1974, Phys. Rev. B 9, 5056 (via refractiveindex.info)",
        "rows": [(0.431, 1.67, 3.17), (0.451, 1.74, 3.28),
                 (0.549, 2.05, 3.82), (0.582, 2.13, 3.96),
                 (0.617, 2.19, 4.11), (0.659, 2.25, 4.27)],
    },
    "Pt": {
        "label": "platinum",
        "source": "Rakic et al. 1998, Appl. Opt. 37, 5271, Lorentz-Drude fit (via refractiveindex.info)",
        "rows": [(0.44967, 1.8503, 3.1379), (0.45144, 1.8546, 3.1479),
                 (0.54908, 2.0885, 3.6984), (0.55123, 2.0939, 3.7106),
                 (0.64977, 2.3692, 4.2524), (0.65232, 2.3770, 4.2658)],
    },
    "W": {
        "label": "tungsten",
        "source": "Weaver, Olson & Lynch 1975, Phys. Rev. B 12, 1293 (via refractiveindex.info)",
        "rows": [(0.4487, 3.314, 2.511), (0.4650, 3.325, 2.574),
                 (0.5489, 3.522, 2.739), (0.5705, 3.524, 2.787),
                 (0.6460, 3.657, 2.925), (0.6524, 3.680, 2.937)],
    },
    "CuZn30": {
        "label": "brass (70% Cu, 30% Zn)",
        "source": "Querry 1985, CRDC-CR-85034, Cu70Zn30 (via refractiveindex.info)",
        "rows": [(0.45, 1.094, 1.829), (0.46, 0.994, 1.883),
                 (0.55, 0.527, 2.765), (0.56, 0.505, 2.860),
                 (0.65, 0.444, 3.695), (0.66, 0.445, 3.778)],
    },
    "SS-ferritic": {
        "label": "ferritic stainless steel (13.5% Cr)",
        "source": "Karlsson & Ribbing 1982, J. Appl. Phys. 53, 6340 (via refractiveindex.info)",
        "rows": [(0.44, 1.4517, 2.7256), (0.46, 1.5372, 2.8162),
                 (0.54, 1.8730, 3.1404), (0.56, 1.9355, 3.2004),
                 (0.64, 2.1685, 3.4507), (0.66, 2.2199, 3.5118)],
    },
}


def interp_nk(rows, lam):
    """Linear interpolation of (n, k) in wavelength between the two bracketing rows."""
    for (l0, n0, k0), (l1, n1, k1) in zip(rows, rows[1:]):
        if l0 <= lam <= l1:
            t = 0.0 if l1 == l0 else (lam - l0) / (l1 - l0)
            return n0 + t * (n1 - n0), k0 + t * (k1 - k0)
    raise ValueError("wavelength %.4f um is not bracketed by the tabulated rows" % lam)


def conductor_reflectance(n, k):
    """Normal-incidence reflectance of a conductor in air."""
    return ((n - 1.0) ** 2 + k * k) / ((n + 1.0) ** 2 + k * k)


def metal_rgb(key):
    """(R_r, R_g, R_b) and the interpolated (n, k) triples for one metal."""
    rows = METALS[key]["rows"]
    nk = [interp_nk(rows, lam) for lam in RGB_WAVELENGTHS_UM]
    return tuple(conductor_reflectance(n, k) for n, k in nk), nk


def luminance(rgb):
    return sum(w * c for w, c in zip(REC709, rgb))


# ---------------------------------------------------------------------------
# Dielectrics: real refractive index at the sodium D line (589.3 nm).
# ---------------------------------------------------------------------------

DIELECTRICS = {
    # One-term Sellmeier fits of Sultanova, Kasarova & Nikolov 2009, Acta Phys. Pol. A 116, 585
    # (coefficients B, C as given by refractiveindex.info), evaluated at 589.3 nm.
    "PMMA": (sellmeier1(1.1819, 0.011313, SODIUM_D_UM),
             "PMMA (acrylic): Sultanova et al. 2009 Sellmeier fit"),
    "PC": (sellmeier1(1.4182, 0.021304, SODIUM_D_UM),
           "polycarbonate: Sultanova et al. 2009 Sellmeier fit"),
    "PS": (sellmeier1(1.4435, 0.020216, SODIUM_D_UM),
           "polystyrene: Sultanova et al. 2009 Sellmeier fit"),
    "cellulose": (sellmeier1(1.124, 0.011087, SODIUM_D_UM),
                  "cellulose: Sultanova et al. 2009 Sellmeier fit"),
    # Zhang et al. 2020, Appl. Opt. 59, 2337 (tabulated, refractiveindex.info), row at 0.59 um.
    "PVC": (1.54238, "PVC: Zhang et al. 2020, tabulated at 590 nm"),
    "PET": (1.56904, "PET: Zhang et al. 2020, tabulated at 590 nm"),
    # Polymer handbook values (Brandrup, Immergut & Grulke, Polymer Handbook, 4th ed.).
    "PP": (1.49, "polypropylene (isotactic): Polymer Handbook, ~1.49"),
    "PA66": (1.53, "nylon 6,6: Polymer Handbook, ~1.53"),
    "ABS": (1.54, "ABS: Polymer Handbook / supplier data, ~1.54 (blend; 1.52-1.54)"),
    "PTFE": (1.35, "PTFE: Polymer Handbook, ~1.35"),
    "NR": (1.519, "natural rubber (cis-polyisoprene): Polymer Handbook, 1.519"),
    "binder": (1.50, "paint binder / clear coat (alkyd, acrylic, polyurethane): ~1.48-1.52, 1.50 taken"),
    "keratin": (1.55, "wool keratin fibre: ~1.55 (textile fibre tables, e.g. Morton & Hearle)"),
    # Glasses, minerals, water (CRC Handbook of Chemistry and Physics; refractiveindex.info).
    "soda-lime": (1.52, "soda-lime glass: CRC Handbook / Rubin 1985, ~1.52"),
    "glaze": (1.55, "silicate ceramic glaze: ~1.50-1.60 (glaze glasses), 1.55 taken"),
    "obsidian": (1.49, "obsidian (rhyolitic glass): 1.48-1.51 (GIA gem reference), 1.49 taken"),
    "calcite": (1.6584, "calcite ordinary ray (marble): Ghosh 1999 / CRC Handbook, 1.658"),
    "quartz": (1.5443, "crystalline quartz ordinary ray: Ghosh 1999 / CRC Handbook, 1.544"),
    "sapphire": (1.7680, "sapphire (Al2O3) ordinary ray: Malitson 1962 / CRC Handbook, 1.768"),
    "diamond": (2.4175, "diamond: Peter 1923 / CRC Handbook, 2.417"),
    "water": (1.3330, "liquid water, 20 C: Hale & Querry 1973 / CRC Handbook, 1.333"),
    "ice": (1.3090, "ice Ih: Warren & Brandt 2008, 1.309"),
    "gypsum": (1.523, "gypsum (CaSO4.2H2O): CRC Handbook / mineral tables, 1.520-1.530, 1.523 taken"),
}


def dielectric_f0(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


# ---------------------------------------------------------------------------
# Diffuse (body) reflectances.
# ColorChecker Classic patches: sRGB (D65) 8-bit values of Pascale 2006, "RGB coordinates
# of the Macbeth ColorChecker" (BabelColor), the values reproduced by Wikipedia's
# ColorChecker article. Luminance Y of white 9.5 = 0.90 and of black 2 = 0.031 (X-Rite).
# CSS named colours: CSS Color Module Level 4 (W3C).
# Scalar albedos: documented broadband/visible reflectances (source in the note).
# ---------------------------------------------------------------------------

SRGB8 = {
    "cc-dark-skin": ((115, 82, 68), "ColorChecker 'dark skin'"),
    "cc-light-skin": ((194, 150, 130), "ColorChecker 'light skin'"),
    "cc-blue-sky": ((98, 122, 157), "ColorChecker 'blue sky'"),
    "cc-orange": ((214, 126, 44), "ColorChecker 'orange'"),
    "cc-purplish-blue": ((80, 91, 166), "ColorChecker 'purplish blue'"),
    "cc-blue": ((56, 61, 150), "ColorChecker 'blue'"),
    "cc-green": ((70, 148, 73), "ColorChecker 'green'"),
    "cc-red": ((175, 54, 60), "ColorChecker 'red'"),
    "cc-yellow": ((231, 199, 31), "ColorChecker 'yellow'"),
    "cc-white": ((243, 243, 242), "ColorChecker 'white 9.5'"),
    "cc-neutral-8": ((200, 200, 200), "ColorChecker 'neutral 8'"),
    "cc-neutral-5": ((122, 122, 121), "ColorChecker 'neutral 5'"),
    "cc-black": ((52, 52, 52), "ColorChecker 'black 2'"),
    "css-burlywood": ((222, 184, 135), "CSS named colour 'burlywood' (light wood)"),
}

SCALAR_ALBEDO = {
    "none": (0.0, "none (bare metal or clear, non-scattering solid)"),
    "snow": (0.90, "fresh snow, visible: ~0.9 or more (Warren 1982, Rev. Geophys. 20, 67)"),
    "office-paper": (0.85, "white office paper: ~0.85 (ISO 2470 brightness ~85-90%)"),
    "cotton": (0.80, "bleached white cotton: ~0.8 in the visible"),
    "plaster": (0.80, "white gypsum plaster: ~0.8 (IES Lighting Handbook reflectance tables)"),
    "concrete": (0.35, "grey Portland-cement concrete: 0.25-0.45 (LBNL Heat Island Group), 0.35 taken"),
    "ptfe": (0.95, "sintered PTFE: >0.95 in the visible (Weidner & Hsia 1981, JOSA 71, 856)"),
}

# Clear water: water-leaving (volume) reflectance ~0.01-0.03 in the blue, near 0 in the
# red (ocean-colour literature, e.g. Morel & Prieur 1977, Limnol. Oceanogr. 22, 709).
LINEAR_ALBEDO = {
    "clear-water": ((0.002, 0.010, 0.030), "clear water body: ~0 (red) to ~0.03 (blue) (Morel & Prieur 1977)"),
}


def diffuse_rgb(key):
    if key in SRGB8:
        rgb8, _ = SRGB8[key]
        return tuple(srgb_to_linear(c) for c in rgb8)
    if key in SCALAR_ALBEDO:
        a, _ = SCALAR_ALBEDO[key]
        return (a, a, a)
    if key in LINEAR_ALBEDO:
        return LINEAR_ALBEDO[key][0]
    raise KeyError(key)


def diffuse_note(key):
    if key in SRGB8:
        rgb8, note = SRGB8[key]
        return "%s sRGB(%d,%d,%d)" % ((note,) + rgb8)
    if key in SCALAR_ALBEDO:
        return SCALAR_ALBEDO[key][1]
    return LINEAR_ALBEDO[key][1]


# ---------------------------------------------------------------------------
# Roughness and specular scale.
# alpha: RMS microfacet slope chosen per surface finish (author's plausible values):
#   mirror / optical polish 0.005-0.008, polished 0.01-0.02, gloss 0.03-0.05,
#   satin / brushed 0.08-0.15, matte / blasted 0.3-0.45, rough granular 0.6-0.7,
#   fibrous (paper, cloth, felt) 0.7-0.9.
# S: fraction of the clean-interface specular reflection kept in the lobe:
#   CLEAN 1.0 (clean interface), WEATHERED 0.7 (dust / weathering film on outdoor
#   surfaces), POROUS 0.5 (fibrous / granular / porous surfaces: gaps between fibres
#   and grains trap part of the interface reflection, which re-emerges as diffuse).
# ---------------------------------------------------------------------------

CLEAN = 1.0
WEATHERED = 0.7
POROUS = 0.5

# Metallic car paint: fraction of the base coat area covered by aluminium flakes.
FLAKE_COVERAGE = 0.9


def exponent_from_alpha(alpha):
    """Blinn-Phong exponent equivalent to a Beckmann RMS slope alpha (n = 2/alpha^2 - 2)."""
    return 2.0 / (alpha * alpha) - 2.0


# ---------------------------------------------------------------------------
# The collection. Fields: name, category, kind, optics, alpha, S, diffuse, finish note.
#   kind "metal":      optics = METALS key
#   kind "dielectric": optics = DIELECTRICS key
#   kind "flake":      optics = METALS key of the flakes; diffuse = pigment colour
# ---------------------------------------------------------------------------

MATERIALS = [
    # --- metals / conductors -------------------------------------------------
    ("mirror-silver", "metal", "metal", "Ag", 0.005, CLEAN, "none", "first-surface mirror"),
    ("polished-gold", "metal", "metal", "Au", 0.015, CLEAN, "none", "polished"),
    ("polished-copper", "metal", "metal", "Cu", 0.02, CLEAN, "none", "polished"),
    ("polished-aluminium", "metal", "metal", "Al", 0.01, CLEAN, "none", "polished"),
    ("brushed-aluminium", "metal", "metal", "Al", 0.10, CLEAN, "none", "brushed (isotropic approx.)"),
    ("sandblasted-aluminium", "metal", "metal", "Al", 0.40, CLEAN, "none", "sand-blasted"),
    ("bright-chromium-plating", "metal", "metal", "Cr", 0.006, CLEAN, "none", "bright electroplate"),
    ("polished-nickel", "metal", "metal", "Ni", 0.02, CLEAN, "none", "polished"),
    ("machined-iron", "metal", "metal", "Fe", 0.15, CLEAN, "none", "turned / milled"),
    ("polished-stainless-steel", "metal", "metal", "SS-ferritic", 0.02, CLEAN, "none", "polished"),
    ("brushed-stainless-steel", "metal", "metal", "SS-ferritic", 0.12, CLEAN, "none", "brushed (isotropic approx.)"),
    ("polished-titanium", "metal", "metal", "Ti", 0.03, CLEAN, "none", "polished"),
    ("bead-blasted-titanium", "metal", "metal", "Ti", 0.45, CLEAN, "none", "bead-blasted"),
    ("polished-platinum", "metal", "metal", "Pt", 0.012, CLEAN, "none", "polished"),
    ("polished-tungsten", "metal", "metal", "W", 0.025, CLEAN, "none", "polished"),
    ("polished-cobalt", "metal", "metal", "Co", 0.04, CLEAN, "none", "polished"),
    ("polished-brass", "metal", "metal", "CuZn30", 0.02, CLEAN, "none", "polished"),
    # --- dielectrics: plastics, glass, ceramics, minerals, water -------------
    ("red-acrylic-sheet", "dielectric", "dielectric", "PMMA", 0.01, CLEAN, "cc-red", "cast sheet"),
    ("black-polycarbonate", "dielectric", "dielectric", "PC", 0.02, CLEAN, "cc-black", "moulded, glossy"),
    ("white-polystyrene", "dielectric", "dielectric", "PS", 0.05, CLEAN, "cc-white", "moulded"),
    ("grey-pvc-pipe", "dielectric", "dielectric", "PVC", 0.08, CLEAN, "cc-neutral-5", "extruded"),
    ("green-pet-sheet", "dielectric", "dielectric", "PET", 0.02, CLEAN, "cc-green", "pigmented sheet"),
    ("natural-polypropylene", "dielectric", "dielectric", "PP", 0.12, CLEAN, "cc-neutral-8", "moulded, semi-matte"),
    ("white-nylon-66", "dielectric", "dielectric", "PA66", 0.20, CLEAN, "cc-white", "machined"),
    ("yellow-abs-brick", "dielectric", "dielectric", "ABS", 0.03, CLEAN, "cc-yellow", "moulded, glossy"),
    ("white-ptfe-block", "dielectric", "dielectric", "PTFE", 0.30, CLEAN, "ptfe", "machined, waxy"),
    ("black-glass-tile", "dielectric", "dielectric", "soda-lime", 0.006, CLEAN, "none", "float glass, black-backed"),
    ("white-glazed-tile", "dielectric", "dielectric", "glaze", 0.01, CLEAN, "cc-white", "glazed"),
    ("blue-glazed-porcelain", "dielectric", "dielectric", "glaze", 0.015, CLEAN, "cc-blue", "glazed"),
    ("polished-carrara-marble", "dielectric", "dielectric", "calcite", 0.03, CLEAN, "cc-neutral-8", "polished"),
    ("polished-obsidian", "dielectric", "dielectric", "obsidian", 0.008, CLEAN, "cc-black", "polished"),
    ("polished-blue-sapphire", "dielectric", "dielectric", "sapphire", 0.006, CLEAN, "cc-purplish-blue", "faceted / polished"),
    ("polished-diamond", "dielectric", "dielectric", "diamond", 0.005, CLEAN, "none", "faceted / polished"),
    ("polished-rock-crystal", "dielectric", "dielectric", "quartz", 0.008, CLEAN, "none", "polished quartz"),
    ("calm-water-surface", "dielectric", "dielectric", "water", 0.02, CLEAN, "clear-water", "calm, capillary ripples"),
    # --- paints, lacquers, varnishes -----------------------------------------
    ("gloss-white-enamel", "paint", "dielectric", "binder", 0.03, CLEAN, "cc-white", "gloss"),
    ("gloss-black-enamel", "paint", "dielectric", "binder", 0.03, CLEAN, "cc-black", "gloss"),
    ("gloss-red-enamel", "paint", "dielectric", "binder", 0.03, CLEAN, "cc-red", "gloss"),
    ("satin-green-paint", "paint", "dielectric", "binder", 0.10, CLEAN, "cc-green", "satin"),
    ("satin-sky-blue-paint", "paint", "dielectric", "binder", 0.10, CLEAN, "cc-blue-sky", "satin"),
    ("matte-white-paint", "paint", "dielectric", "binder", 0.40, CLEAN, "cc-white", "flat / matte"),
    ("matte-black-paint", "paint", "dielectric", "binder", 0.45, CLEAN, "cc-black", "flat / matte"),
    ("piano-black-lacquer", "paint", "dielectric", "binder", 0.006, CLEAN, "cc-black", "polished lacquer"),
    ("varnished-walnut-board", "paint", "dielectric", "binder", 0.05, CLEAN, "cc-dark-skin", "satin-gloss varnish"),
    ("metallic-silver-car-paint", "paint", "flake", "Al", 0.20, CLEAN, "cc-neutral-8", "Al flakes in tinted coat"),
    ("metallic-blue-car-paint", "paint", "flake", "Al", 0.20, CLEAN, "cc-blue", "Al flakes in tinted coat"),
    ("metallic-red-car-paint", "paint", "flake", "Al", 0.20, CLEAN, "cc-red", "Al flakes in tinted coat"),
    # --- rough materials -----------------------------------------------------
    ("white-office-paper", "rough", "dielectric", "cellulose", 0.70, POROUS, "office-paper", "uncoated paper"),
    ("white-cotton-fabric", "rough", "dielectric", "cellulose", 0.85, POROUS, "cotton", "woven cloth"),
    ("blue-denim", "rough", "dielectric", "cellulose", 0.80, POROUS, "cc-blue", "twill cloth"),
    ("grey-wool-felt", "rough", "dielectric", "keratin", 0.90, POROUS, "cc-neutral-5", "pressed felt"),
    ("unfinished-pine-board", "rough", "dielectric", "cellulose", 0.50, POROUS, "css-burlywood", "planed, unfinished"),
    ("fresh-snow", "rough", "dielectric", "ice", 0.60, POROUS, "snow", "granular"),
    ("black-tyre-rubber", "rough", "dielectric", "NR", 0.35, WEATHERED, "cc-black", "carbon-black filled, worn"),
    ("white-gypsum-plaster", "rough", "dielectric", "gypsum", 0.70, POROUS, "plaster", "trowelled, porous"),
    ("grey-concrete", "rough", "dielectric", "quartz", 0.80, WEATHERED, "concrete", "cast, weathered"),
    ("unglazed-terracotta", "rough", "dielectric", "quartz", 0.65, WEATHERED, "cc-orange", "fired clay"),
    ("dry-quartz-sand", "rough", "dielectric", "quartz", 0.70, POROUS, "cc-light-skin", "granular"),
]

HEADER = ["material", "d_r", "d_g", "d_b", "s_r", "s_g", "s_b", "F0", "n", "category"]
CATEGORIES = ("metal", "dielectric", "paint", "rough")


def build():
    """Return a list of dicts, one per material, with the AS parameters and the inputs."""
    out = []
    for name, category, kind, optics, alpha, scale, diffuse, finish in MATERIALS:
        n_exp = exponent_from_alpha(alpha)
        rec = {"name": name, "category": category, "kind": kind, "optics": optics,
               "alpha": alpha, "S": scale, "diffuse": diffuse, "finish": finish, "n": n_exp}
        if kind == "metal":
            r_rgb, nk = metal_rgb(optics)
            f0 = luminance(r_rgb)
            rec.update(F0=f0, s=tuple(scale * r / f0 for r in r_rgb),
                       d=diffuse_rgb(diffuse), R=r_rgb, nk=nk)
        elif kind == "dielectric":
            eta = DIELECTRICS[optics][0]
            f0 = dielectric_f0(eta)
            rec.update(F0=f0, s=(scale, scale, scale), d=diffuse_rgb(diffuse), eta=eta)
        elif kind == "flake":
            r_rgb, nk = metal_rgb(optics)
            f0 = luminance(r_rgb)
            tint = diffuse_rgb(diffuse)
            rec.update(F0=f0, s=tuple(scale * t * r / f0 for t, r in zip(tint, r_rgb)),
                       d=tuple((1.0 - FLAKE_COVERAGE) * t for t in tint), R=r_rgb, nk=nk)
        else:
            raise ValueError(kind)
        out.append(rec)
    return out


def check(recs):
    names = [r["name"] for r in recs]
    assert len(names) == len(set(names)), "duplicate names"
    for r in recs:
        assert r["category"] in CATEGORIES, r["name"]
        assert all(c in "abcdefghijklmnopqrstuvwxyz0123456789-" for c in r["name"]), r["name"]
        vals = list(r["d"]) + list(r["s"]) + [r["F0"], r["n"]]
        assert all(math.isfinite(v) for v in vals), r["name"]
        assert all(v >= 0.0 for v in r["d"]) and all(v >= 0.0 for v in r["s"]), r["name"]
        assert 0.0 <= r["F0"] <= 1.0 and r["n"] > 0.0, r["name"]


def fmt(x):
    """6 significant digits; exact zeros are written as 0."""
    if x == 0.0:
        return "0"
    return "%.6g" % x


def csv_text(recs):
    lines = [",".join(HEADER)]
    for r in recs:
        row = [r["name"]] + [fmt(v) for v in r["d"]] + [fmt(v) for v in r["s"]] \
            + [fmt(r["F0"]), fmt(r["n"]), r["category"]]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def markdown_table(recs):
    rows = ["| material | category | optical input | source of the optical input | finish | alpha | n | S | F0 | diffuse (body) reflectance |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in recs:
        if r["kind"] == "dielectric":
            label, source = DIELECTRICS[r["optics"]][1].split(": ", 1)
            optical = "%s, eta = %.4f" % (label, r["eta"])
        else:
            metal = METALS[r["optics"]]
            source = metal["source"]
            nk = ", ".join("%.3f+%.3fi" % (n, k) for n, k in r["nk"])
            optical = "%s%s, n+ik = %s; R_rgb = %s" % (
                "flakes of " if r["kind"] == "flake" else "", metal["label"], nk,
                ", ".join("%.3f" % x for x in r["R"]))
        rows.append("| `%s` | %s | %s | %s | %s | %g | %s | %g | %s | %s |" % (
            r["name"], r["category"], optical, source, r["finish"], r["alpha"], fmt(r["n"]),
            r["S"], fmt(r["F0"]), diffuse_note(r["diffuse"])))
    return "\n".join(rows) + "\n"


def main(argv):
    recs = build()
    check(recs)
    text = csv_text(recs)
    if "--stdout" in argv:
        sys.stdout.write(text)
    else:
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "default_collection.csv")
        with open(path, "w", encoding="ascii", newline="\n") as f:
            f.write(text)
        sys.stderr.write("wrote %d materials to %s\n" % (len(recs), path))
    if "--table" in argv:
        sys.stdout.write(markdown_table(recs))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
