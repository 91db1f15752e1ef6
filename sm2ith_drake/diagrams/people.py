"""The simulated people and their motion capture, added to a builder: one
helper for the simulation and the hardware driver alike.
"""

from sm2ith_drake.systems.humans import CrowdSimulator, MocapSensor


def AddCrowd(builder, scenario, robot, segments):
    return builder.AddNamedSystem(
        "crowd",
        CrowdSimulator(
            robot,
            scenario.humans,
            obstacle_segments=segments,
            time_step=scenario.crowd_time_step,
            tau=scenario.prediction.tau,
            tau_obs=scenario.prediction.tau_obs,
            model=scenario.prediction,
            phases=[phase.name for phase in scenario.sequence],
        ),
    )


def AddMocap(builder, scenario):
    pc = scenario.perception
    return builder.AddNamedSystem(
        "mocap",
        MocapSensor(
            period=pc.period,
            noise=pc.noise,
            dropout_probability=pc.dropout_probability,
            seed=scenario.random_seed,
        ),
    )
