"""Published numbers: the paper's (paper.py) and the literature's homogenised constants of IceSL foams (literature.py), each with its source."""
