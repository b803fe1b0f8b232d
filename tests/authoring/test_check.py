"""`qdframe check-model` (qdframe/authoring/check.py): pieces and gradients against finite differences."""

import json

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.authoring.check import ModelCheckError, add_check_parser, check_model, main_check
from qdframe.cli import main as cli_main
from qdframe.cli import _Parser
from qdframe.model import Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, SignTerm, Surface


@pytest.mark.parametrize("name", sorted(registry.available("models")))
def test_every_registered_model_passes(name):
    report = check_model(qdframe.load_model(name), samples=16)
    assert report.ok, report.table()
    assert report.pieces and all(p.worst_error < 1e-6 for p in report.pieces)


def _linear(gradient):
    gradient = np.asarray(gradient, float)
    return lambda y: (y @ gradient, np.broadcast_to(gradient, y.shape).copy())


class Faulty(InclusionModel):
    """Two states; `fault` picks which piece is broken."""

    name = "test-faulty"
    state_names = ("a", "b")
    control_names = ("u",)
    default_x0 = (0.2, -0.1)
    fault = "none"

    def blocks(self):
        fault = self.fault

        def square(y):  # z_a = a²: the gradient 2a, or a wrong one
            grad = np.zeros_like(y)
            grad[:, 0] = (3.0 if fault == "gradient" else 2.0) * y[:, 0]
            value = y[:, 0] ** 2
            if fault == "nan":
                value = np.where(y[:, 0] > 0, np.nan, value)
            return value, grad

        def circle(y, psi):  # c = ⟨(b, 0), ψ⟩ + 1 on S_1 … a min-group with a y-gradient
            grad = np.zeros((y.shape[0], 1, y.shape[1]))
            grad[:, 0, 1] = psi[:, 0] * (0.5 if fault == "min" else 1.0)
            return (y[:, 1] * psi[:, 0] + 1.0)[:, None], grad

        def circle_values(y, psi):  # circle's values alone, or wrong ones
            return (y[:, 1] * psi[:, 0] + (1.1 if fault == "values" else 1.0))[:, None]

        def shape(y):
            values = np.stack([y[:, 1], -y[:, 1]], axis=1)[:, :, None]
            jac = np.zeros((y.shape[0], 2, 1, y.shape[1]))
            jac[:, 0, 0, 1], jac[:, 1, 0, 1] = 1.0, -1.0
            if fault == "shape":
                return values[:, :, 0], jac
            return values, jac

        def amplitude(y):
            values = np.stack([y[:, 2], -y[:, 2]], axis=1)
            grads = np.zeros((y.shape[0], 2, y.shape[1]))
            grads[:, 0, 2], grads[:, 1, 2] = 1.0, -1.0
            if fault == "negative":
                values = values - 10.0
            return values, grads

        return (
            SetBlock.equation(0, square, name="a'", signs=(SignTerm((amplitude,), _linear([0, -1, 0])),)),
            SetBlock((1,), (MaxGroup(shape, "±b"),), (MinGroup(circle, "circle", values=circle_values),), name="b'"),
        )

    def surface(self):
        wrong = self.fault == "surface"
        return Surface(lambda x: (x[:, :1] * x[:, 1:2], np.stack([x[:, 1:2], x[:, :1] * (2.0 if wrong else 1.0)], axis=2)))

    def cost(self):
        def cost(y):
            values = np.stack([np.sin(y[:, 0]), y[:, 2]], axis=1)
            grads = np.zeros((y.shape[0], 2, 3))
            grads[:, 0, 0] = np.cos(y[:, 0]) if self.fault != "cost" else 1.0
            grads[:, 1, 2] = 1.0
            return values, grads

        return Cost(max_groups=(cost,))


def _faulty(fault):
    return type(f"Faulty_{fault}", (Faulty,), {"fault": fault})()


def test_a_correct_model_with_every_kind_of_piece_passes():
    report = check_model(_faulty("none"))
    assert report.ok, report.table()
    labels = " ".join(p.label for p in report.pieces)
    for kind in ("max-group", "min-group", "switch", "amplitude", "surface", "cost"):
        assert kind in labels


@pytest.mark.parametrize(
    "fault, piece, status",
    [
        ("gradient", "a' max-group", "wrong gradient"),
        ("min", "min-group 'circle'", "wrong gradient"),
        ("values", "min-group 'circle' values", "values differ"),
        ("surface", "surface", "wrong gradient"),
        ("cost", "cost max-group", "wrong gradient"),
        ("nan", "a' max-group", "non-finite"),
        ("shape", "max-group '±b'", "bad shape"),
        ("negative", "amplitude", "negative amplitude"),
    ],
)
def test_a_broken_piece_fails_and_is_named(fault, piece, status):
    report = check_model(_faulty(fault))
    assert not report.ok
    (failure,) = report.failures
    assert piece in failure.label and failure.status == status, report.table()
    assert piece in report.message() and status in report.message()


def test_a_wrong_gradient_is_reported_with_both_values():
    failure = check_model(_faulty("gradient")).failures[0]
    assert failure.worst_error > 0.1
    assert "∂/∂a" in failure.detail and "finite differences give" in failure.detail


def test_kinks_are_not_errors():
    """|x1 − x2| in paper-7.1's min-group: samples near the kink are differenced again, finer."""
    report = check_model(qdframe.load_model("paper-7.1"), samples=2000, seed=3)
    assert report.ok, report.table()


def _parse(argv):
    parser = _Parser(prog="qdframe")
    add_check_parser(parser.add_subparsers(dest="command", required=True, parser_class=_Parser))
    return parser.parse_args(argv)


def test_command_prints_a_table_and_writes_json(tmp_path, capsys):
    out = tmp_path / "check.json"
    assert main_check(_parse(["check-model", "paper-7.2", "--samples", "8", "--json", str(out)])) == 0
    text = capsys.readouterr().out
    assert "paper-7.2" in text and "min-group" in text and "all pieces agree" in text
    data = json.loads(out.read_text())
    assert data["ok"] and data["pieces"][0]["status"] == "ok"


def test_command_fails_with_one_line_and_exit_status_1(monkeypatch, capsys):
    broken = type("Broken", (Faulty,), {"fault": "gradient", "name": "broken"})
    real = registry.lookup

    def lookup(kind, name):
        if kind == "models" and name == "broken":
            return registry.Entry("models", "broken", "test", "test:Broken", broken)
        return real(kind, name)

    monkeypatch.setattr("qdframe.registry.lookup", lookup)
    with pytest.raises(ModelCheckError, match="wrong gradient"):
        main_check(_parse(["check-model", "broken"]))
    capsys.readouterr()
    assert cli_main(["check-model", "broken"]) == 1
    captured = capsys.readouterr()
    assert "wrong gradient" in captured.out  # the table
    assert captured.err.count("\n") == 1 and captured.err.startswith("qdframe: error: model 'broken'")


@pytest.mark.parametrize("argv", [["no-such-model"], ["paper-7.1", "--samples", "0"], ["paper-7.1", "--tol", "-1"]])
def test_bad_arguments_exit_2_with_one_line(argv, capsys):
    assert cli_main(["check-model", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("fault, piece", [("hessian", "cost Hessian"), ("terminal", "terminal cost Hessian")])
def test_a_wrong_cost_hessian_or_terminal_cost_is_named(fault, piece):
    """The optimal-control hooks (issue 53): a smooth cost's Hessian and a terminal cost's
    gradient and Hessian are held to differences of the gradients like every piece."""

    class Smooth(Faulty):
        def cost(self):
            def integrand(y):  # u² + a²
                return (y[:, 2] ** 2 + y[:, 0] ** 2)[:, None], np.stack([2 * y[:, 0], 0 * y[:, 1], 2 * y[:, 2]], 1)[:, None]

            def hessian(y):
                out = np.zeros((y.shape[0], 3, 3))
                out[:, 0, 0], out[:, 2, 2] = 2.0, 3.0 if self.fault == "hessian" else 2.0
                return out

            def terminal(x):  # (a − 1)²·b
                hess = np.array([[2 * x[1], 2 * (x[0] - 1)], [2 * (x[0] - 1), 0.0]])
                if self.fault == "terminal":
                    hess[0, 1] = hess[1, 0] = 0.0
                return (x[0] - 1) ** 2 * x[1], np.array([2 * (x[0] - 1) * x[1], (x[0] - 1) ** 2]), hess

            return Cost(max_groups=(integrand,), hessian=hessian, terminal=terminal)

    assert check_model(type("Right", (Smooth,), {"fault": "none"})()).ok
    report = check_model(type("Wrong", (Smooth,), {"fault": fault})())
    (failure,) = report.failures
    assert failure.label == piece and failure.status == "wrong gradient", report.table()
