"""The tripod sheet: geometry and tet mesh, spiral fibre field, grading, IceSL export."""
