"""Quantum stage.

Batched circuits and simulators, noise channels, the UU-dagger test, centroid
training, the VQC and the hardware-time model.
"""
