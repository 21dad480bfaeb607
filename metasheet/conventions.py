"""Units and index conventions shared by every module.

Units: millimetre, newton, megapascal (N/mm^2), second, tonne. Hence gravity is
9810 mm/s^2 and a density of 1.19 g/cm^3 is 1.19e-9 t/mm^3.

Angles are degrees in configs, the CLI and output files; radians inside the code.

Voigt order is 11, 22, 33, 23, 13, 12 with *engineering* shear strains
(gamma_23 = 2 eps_23). The transverse-isotropic longitudinal axis ``l`` is local
axis 3.

Arrays at public boundaries are ``(n, 3)`` like meshio/trimesh/pyvista.
"""

import numpy as np

GRAVITY = 9810.0  # [mm/s^2]
TPU_DENSITY = 1.19e-9  # [t/mm^3]

#: Voigt index -> (i, j) tensor indices, order 11, 22, 33, 23, 13, 12.
VOIGT_PAIRS = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))

#: Factor turning a Voigt vector/matrix into Mandel form (sqrt 2 on shear terms).
MANDEL_SCALE = np.array([1.0, 1.0, 1.0, np.sqrt(2.0), np.sqrt(2.0), np.sqrt(2.0)])
