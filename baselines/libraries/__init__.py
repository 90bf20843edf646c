"""One module per external kinematics library (the ``[libs]`` extra), each registering its
methods in :mod:`ikbench.methods.registry`; importing one needs its library."""
