"""The predictor a PredictionConfig names."""

from sm2ith_drake.control.prediction.base import Cvmm, React
from sm2ith_drake.control.prediction.orca_kkt import OrcaKkt


def MakePredictor(
    config,
    *,
    horizon: int,
    time_step: float,
    robot=None,
    obstacles=(),
    human_radius: float = 0.3,
):
    """The predictor named by ``config.predictor``."""
    if config.predictor == "react":
        return React(config, horizon=horizon, time_step=time_step)
    if config.predictor == "cvmm":
        return Cvmm(config, horizon=horizon, time_step=time_step)
    if config.predictor == "orca_kkt":
        return OrcaKkt(
            config,
            horizon=horizon,
            time_step=time_step,
            robot=robot,
            obstacles=obstacles,
            human_radius=human_radius,
        )
    raise ValueError(f"unknown predictor '{config.predictor}'")
