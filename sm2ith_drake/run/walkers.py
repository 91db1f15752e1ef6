"""Scripted people pacing across the robot's way: the benchmark's crowd
(``sm2ith bench``) and the driver's (``sm2ith driver --humans N``)."""

from __future__ import annotations

from sm2ith_drake.scenario import HumanConfig


def ScriptedWalkers(
    count: int,
    *,
    x_start: float,
    x_span: float,
    half_width: float,
    base_speed: float,
) -> list[HumanConfig]:
    """``count`` people pacing back and forth across y ∈ [−half_width,
    half_width], spread evenly over x ∈ [x_start, x_start + x_span].

    Person j walks at x = x_start + x_span · j / (count − 1), starts on the
    side +half_width (even j) or −half_width (odd j), loops between the two
    sides at base_speed + 0.1 (j mod 3) m/s and ignores the robot (scripted,
    so the crowd is the same whatever the robot does).
    """
    walkers = []
    for j in range(count):
        x = x_start + x_span * j / max(count - 1, 1)
        side = half_width if j % 2 == 0 else -half_width
        walkers.append(
            HumanConfig(
                behavior="scripted",
                start=[x, side],
                waypoints=[[x, -side], [x, side]],
                loop=True,
                speed=base_speed + 0.1 * (j % 3),
            )
        )
    return walkers
