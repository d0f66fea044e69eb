"""Constitutive models: "hencky" (paper (31)) and "quadratic" (paper (26)), plus a registry."""

from .base import Model, available_models, get_model, register_model
from .hencky import HENCKY
from .quadratic import QUADRATIC

__all__ = ["Model", "register_model", "get_model", "available_models", "HENCKY", "QUADRATIC"]
