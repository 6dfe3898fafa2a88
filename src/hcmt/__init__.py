"""hcmt: learned simulation of flexible bodies in contact (Hierarchical Contact Mesh Transformer)."""

__version__ = "0.1.0"
