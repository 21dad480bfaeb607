"""The robot: corotational anisotropic tet FEM (:mod:`.body`), and on top of it the rigid
couplings, assemblies, static solver, Jacobian and inverse QP of the paper's Section III."""
