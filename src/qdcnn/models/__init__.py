"""Classical CNN baselines (PilotNet, ResNet-50) in plain PyTorch; torch is the optional ``dnn`` extra."""
