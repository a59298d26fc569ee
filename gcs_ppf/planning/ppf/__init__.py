"""The PPF step: the numba kernel (the paper's equations) and its plain-numpy reference."""
