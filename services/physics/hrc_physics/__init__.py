"""hrc-cosim physics service: the pybullet world and the simulation clock."""
