"""Quantum stage: circuits, batched simulators, noise channels, UU-dagger, centroid training, VQC, hardware-time model."""
