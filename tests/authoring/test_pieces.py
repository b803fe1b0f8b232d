"""Ready-made pieces for hand-written models (qdframe/ready_pieces.py): values and
gradients, and a model built from them passes check-model."""

import numpy as np

import qdframe
from qdframe.authoring import abs_sum, affine, check_model, constant, coordinate
from qdframe.model import InclusionModel, SetBlock, SignTerm


def test_affine_constant_and_coordinate_give_values_and_gradients():
    y = np.array([[1.0, 2.0, 3.0], [-1.0, 0.5, 0.0]])
    value, grad = affine({0: 2.0, 2: -1.0}, 3, constant=0.5)(y)
    assert np.allclose(value, [0.5 + 2 - 3, 0.5 - 2]) and np.allclose(grad, [[2, 0, -1]] * 2)
    value, grad = constant(4.0, 3)(y)
    assert np.allclose(value, 4.0) and not grad.any()
    value, grad = coordinate(1, 3)(y)
    assert np.allclose(value, y[:, 1]) and np.allclose(grad, [[0, 1, 0]] * 2)


def test_abs_sum_is_one_group_of_plus_and_minus_per_coordinate():
    groups = abs_sum([0, 2], 1.5, 3)
    y = np.array([[1.0, 9.0, -2.0]])
    maxima = [group(y)[0].max(axis=1)[0] for group in groups]
    assert np.allclose(maxima, [1.5, 3.0])
    values, grads = groups[1](y)
    assert values.shape == (1, 2) and np.allclose(grads[0], [[0, 0, 1.5], [0, 0, -1.5]])


class BrakedCart(InclusionModel):
    """p' = v, v' ∈ 1 − 0.5·Sgn(v): written with the ready-made pieces."""

    name = "braked-cart"
    state_names = ("p", "v")
    default_x0 = (0.0, 0.0)
    end_indices = (1,)
    default_end_values = (0.5,)

    def blocks(self):
        return (
            SetBlock.equation(0, coordinate(1, 2), "p' = v"),
            SetBlock.equation(1, constant(1.0, 2), "v' ∈ 1 − 0.5·Sgn(v)",
                              (SignTerm(0.5, affine({1: -1.0}, 2), name="0.5·Sgn(−v)"),)),
        )


def test_a_model_of_ready_made_pieces_checks_and_solves():
    assert check_model(BrakedCart(), samples=16).ok
    assert qdframe.solve(BrakedCart(), nodes=51).converged
