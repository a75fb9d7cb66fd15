"""The simulated rig of the paper's laboratory setup (Melchiorri 2000, §V, Fig. 8)."""
