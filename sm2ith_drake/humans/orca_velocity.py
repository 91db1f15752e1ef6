"""RVO2's velocity selection: ``linearProgram2`` on the speed disc, and
``linearProgram3`` (minimum penetration, obstacle lines kept hard) when the
ORCA lines are infeasible (van den Berg et al. 2011).
"""

import numpy as np

from sm2ith_drake.humans.orca import RVO_EPSILON, _Det, _Normalize, orca_half_planes


def _LinearProgram1(points, dirs, line_no, radius, opt, direction_opt):
    p, d = points[line_no], dirs[line_no]
    dot = float(p @ d)
    disc = dot * dot + radius * radius - float(p @ p)
    if disc < 0.0:
        return None
    sq = np.sqrt(disc)
    t_left, t_right = -dot - sq, -dot + sq
    for i in range(line_no):
        denominator = _Det(d, dirs[i])
        numerator = _Det(dirs[i], p - points[i])
        if abs(denominator) <= RVO_EPSILON:
            if numerator < 0.0:
                return None
            continue
        t = numerator / denominator
        if denominator >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        return p + (t_right if float(opt @ d) > 0.0 else t_left) * d
    t = float(d @ (opt - p))
    return p + min(max(t, t_left), t_right) * d


def _LinearProgram2(points, dirs, radius, opt, direction_opt):
    if direction_opt:
        result = opt * radius
    elif float(opt @ opt) > radius * radius:
        result = _Normalize(opt) * radius
    else:
        result = opt.copy()
    for i in range(len(points)):
        if _Det(dirs[i], points[i] - result) > 0.0:
            new = _LinearProgram1(points, dirs, i, radius, opt, direction_opt)
            if new is None:
                return i, result
            result = new
    return len(points), result


def _LinearProgram3(points, dirs, num_obstacle_lines, begin, radius, result):
    distance = 0.0
    for i in range(begin, len(points)):
        if _Det(dirs[i], points[i] - result) > distance:
            proj_p = list(points[:num_obstacle_lines])
            proj_d = list(dirs[:num_obstacle_lines])
            for j in range(num_obstacle_lines, i):
                determinant = _Det(dirs[i], dirs[j])
                if abs(determinant) <= RVO_EPSILON:
                    if float(dirs[i] @ dirs[j]) > 0.0:
                        continue
                    point = 0.5 * (points[i] + points[j])
                else:
                    point = (
                        points[i]
                        + (_Det(dirs[j], points[i] - points[j]) / determinant) * dirs[i]
                    )
                proj_p.append(point)
                proj_d.append(_Normalize(dirs[j] - dirs[i]))
            proj_p = np.array(proj_p).reshape(-1, 2)
            proj_d = np.array(proj_d).reshape(-1, 2)
            fail, new = _LinearProgram2(
                proj_p, proj_d, radius, np.array([-dirs[i][1], dirs[i][0]]), True
            )
            if fail >= len(proj_p):
                result = new
            distance = _Det(dirs[i], points[i] - result)
    return result


def orca_velocity(
    position,
    velocity,
    radius,
    other_positions,
    other_velocities,
    other_radii,
    *,
    preferred_velocity,
    max_speed,
    tau=2.0,
    tau_obs=0.5,
    time_step,
    shares=None,
    obstacles=(),
    neighbor_dist=np.inf,
):
    """The velocity RVO2 chooses for the agent (see :func:`orca_half_planes`
    for the arguments): the closest to ``preferred_velocity`` within
    ``max_speed`` satisfying every ORCA line, or, if none does, the one that
    least violates the agent lines while keeping the obstacle lines."""
    points, dirs, num_obstacle = orca_half_planes(
        position,
        velocity,
        radius,
        other_positions,
        other_velocities,
        other_radii,
        tau=tau,
        tau_obs=tau_obs,
        time_step=time_step,
        shares=shares,
        obstacles=obstacles,
        max_speed=max_speed,
        neighbor_dist=neighbor_dist,
    )
    opt = np.asarray(preferred_velocity, dtype=float)
    fail, result = _LinearProgram2(points, dirs, max_speed, opt, False)
    if fail < len(points):
        result = _LinearProgram3(points, dirs, num_obstacle, fail, max_speed, result)
    return result
