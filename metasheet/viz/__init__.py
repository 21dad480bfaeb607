"""Off-screen pictures and plots, one module per stage area."""
