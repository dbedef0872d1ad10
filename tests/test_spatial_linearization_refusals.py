"""The public functions of ``ctmm.spatial_linearization`` refuse a non-model with a ``ModelError`` naming the
function and what it got (they raised ``AttributeError`` before)."""
from __future__ import annotations

import pytest

import ctmm.spatial_linearization as spatial_linearization
from ctmm.errors import ModelError


@pytest.mark.parametrize("function", ["tangent_names", "input_names", "static_equilibrium", "unstable_directions",
                                      "operating_point", "linearize_spatial"])
@pytest.mark.parametrize("model", [3, None, "arm", [1, 2]])
def test_a_non_model_is_refused_by_name(function, model):
    call = getattr(spatial_linearization, function)
    arguments = (model, [0.0]) if function == "unstable_directions" else (model,)
    with pytest.raises(ModelError, match=rf"{function}: model must be a ctmm.spatial.SpatialModel, got "
                                         rf"{type(model).__name__}"):
        call(*arguments)
