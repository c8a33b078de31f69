"""Data: image input and output, synthetic road scenes, recording loaders and labels."""
