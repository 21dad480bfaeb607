"""Published homogenised constants of IceSL foams, to compare ours with.

Source: the paper's authors' public code (github.com/VannesteFelix/anisotropy,
``examples/Tripod/homogenized_value.py``): two printed-foam families homogenised at four
measured relative densities each, moduli normalised by the base material's E_s and shear
moduli by G_s = E_s / 2.6 (nu_s = 0.3), E_s = 12 MPa (TPU NinjaFlex). The "transverse" foam
has x soft and y, z stiff; the paper's constants (:data:`metasheet.published.paper.PAPER_FOAM`) are
this table interpolated linearly at rho = 0.15, which :func:`authors_constants` reproduces
(tested). How the table was computed (mesh, resolution, tool) is not in the code.

Mapping to metasheet's transverse-isotropic constants about the soft axis l = x:
E_t = mean(E_y, E_z), E_l = E_x, nu_t = nu_yz, nu_tl = nu_zx (the large one, 0.39-0.51),
mu_l = mean(G_zx, G_xy). For the isotropic foam, every value is the mean over axes.
"""

from __future__ import annotations

import numpy as np

from ..errors import check_range

#: E_s [MPa] and G_s = E_s / 2.6 [MPa] of the table's normalisation.
E_S = 12.0
G_S = E_S / 2.6

#: Columns: relative density, E_x, E_y, E_z (/E_s), nu_xy, nu_zx, nu_yz, G_yz, G_zx, G_xy (/G_s).
_COLUMNS = ("density", "E_x", "E_y", "E_z", "nu_xy", "nu_zx", "nu_yz", "G_yz", "G_zx", "G_xy")
_TRANSVERSE = np.array([
    [0.0918029, 0.179756, 0.263914, 0.342217],
    [0.007190947838757, 0.008230111658949, 0.009439109647396, 0.010941129587942],
    [0.067710467868908, 0.146297859786932, 0.221414943029807, 0.294252728094559],
    [0.061813265353562, 0.137214491707188, 0.210416420608331, 0.28428001329836],
    [0.0403209753676, 0.024348518722795, 0.020475459214172, 0.019080764420993],
    [0.389564230585755, 0.429701550085775, 0.471791033895048, 0.505847340792237],
    [0.240368391679546, 0.272528832201562, 0.278932858477574, 0.281555456870959],
    [0.026972453606694, 0.056665350771762, 0.085678017994847, 0.114317962073604],
    [0.002803520943703, 0.004073999158208, 0.00547641404988, 0.00710862559679],
    [0.002701389044616, 0.00383344734316, 0.005138979737874, 0.006672898755323],
])
_ISOTROPIC = np.array([
    [0.0900707, 0.153433, 0.232295, 0.32966],
    [0.026222034111765, 0.046987667255342, 0.079265015264225, 0.131738535842246],
    [0.026305036832142, 0.04697078706972, 0.079105092287369, 0.131550665955392],
    [0.02155869748475, 0.036844459422693, 0.063105750297705, 0.109824716818926],
    [0.290057519282359, 0.290814572184721, 0.284144245516017, 0.270471898762415],
    [0.229459019286116, 0.220986492603532, 0.225023244875417, 0.234785024931196],
    [0.282967785817053, 0.285273329337783, 0.285355572009707, 0.282608914130423],
    [0.011916052577042, 0.020926027163809, 0.034778835113764, 0.056832637396845],
    [0.011661479953317, 0.020442071408138, 0.034113645260998, 0.055879274748158],
    [0.00977624404956, 0.017553738925774, 0.030064296511316, 0.049916264241792],
])
TABLES = {"transverse": _TRANSVERSE, "isotropic": _ISOTROPIC}
SOURCE = "authors' public code, VannesteFelix/anisotropy examples/Tripod/homogenized_value.py"


def authors_table(kind: str = "transverse") -> dict[str, np.ndarray]:
    """The raw table of ``kind`` ("transverse" | "isotropic"): column -> (4,) normalised values."""
    if kind not in TABLES:
        raise ValueError(f"kind: {kind!r}: expected one of {', '.join(TABLES)}")
    return dict(zip(_COLUMNS, TABLES[kind]))


def authors_constants(rho, kind: str = "transverse") -> dict[str, np.ndarray]:
    """The five constants [MPa, -] of the authors' foam at relative density ``rho``.

    Linear interpolation in density between the table's four rows (as the authors did for
    the paper's constants); ``rho`` within the table's range (about 0.09 to 0.34).
    """
    t = authors_table(kind)
    d = t["density"]
    rho = np.asarray(rho, float)
    for r in np.atleast_1d(rho):
        check_range("relative_density", float(r), float(d[0]), float(d[-1]))

    def at(name):
        return np.interp(rho, d, t[name])

    if kind == "isotropic":
        e = (at("E_x") + at("E_y") + at("E_z")) / 3 * E_S
        nu = (at("nu_xy") + at("nu_zx") + at("nu_yz")) / 3
        g = (at("G_yz") + at("G_zx") + at("G_xy")) / 3 * G_S
        return {"E_t": e, "E_l": e, "nu_t": nu, "nu_tl": nu, "mu_l": g}
    return {"E_t": 0.5 * (at("E_y") + at("E_z")) * E_S, "E_l": at("E_x") * E_S, "nu_t": at("nu_yz"),
            "nu_tl": at("nu_zx"), "mu_l": 0.5 * (at("G_zx") + at("G_xy")) * G_S}
