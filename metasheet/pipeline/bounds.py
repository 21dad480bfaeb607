"""Physical ranges of the material parameters every stage shares (pydantic ``Field`` bounds).

A value outside them is a typing slip, not a material: ``density = 1e300`` or ``mu_l = 1e-300``
passed as merely positive and then failed deep inside a solver (an SVD that did not converge).

- Young's and shear moduli [MPa]: from 1 Pa (the softest gels) to 2 TPa (above diamond's 1.05).
- Mass densities [t/mm^3]: from 1e-13 (0.1 kg/m^3, below the lightest aerogels) to 1e-7
  (100,000 kg/m^3, above osmium's 22,590).
"""

#: Field bounds of a Young's or shear modulus [MPa].
MODULUS = {"ge": 1e-6, "le": 2e6}

#: Field bounds of a mass density [t/mm^3].
MASS_DENSITY = {"ge": 1e-13, "le": 1e-7}
