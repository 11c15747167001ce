"""The model layer: symbolic mechanism definitions, derivation, generated numeric code."""
from csim.model.definition import (
    Drawing,
    Load,
    MechanismDefinition,
    Observable,
    Parameter,
    PlanarBody,
)
from csim.model.numeric import NumericModel, build_numeric_model

__all__ = [
    "Drawing",
    "Load",
    "MechanismDefinition",
    "NumericModel",
    "Observable",
    "Parameter",
    "PlanarBody",
    "build_numeric_model",
]
