"""Rigid-body geometry: pose containers, pose matrices and rotation chains, frame changes of
many vectors at once, and element-wise vector kernels."""
