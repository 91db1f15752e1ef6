"""Helpers for tests that step an MpcController without the HumanPredictor
system."""


def FirstPrediction(controller, estimate, q0=None, nu0=None):
    """The HumanPredictor's output for ``estimate`` at a first step."""
    model = controller.human_predictor
    prediction, _ = model.Predict(
        model.InitialState(),
        estimate=estimate,
        q0=q0,
        nu0=nu0,
        warm_start_inputs=controller.WarmStartInputs(controller.InitialState()),
    )
    return prediction


def FirstStep(controller, estimate, q0, nu0, targets):
    """The controller's first step with the people of ``estimate``."""
    return controller.Step(
        controller.InitialState(),
        time_now=0.0,
        q0=q0,
        nu0=nu0,
        targets=targets,
        prediction=FirstPrediction(controller, estimate, q0, nu0),
    )
