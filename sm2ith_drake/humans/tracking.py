"""Human tracking: a constant-velocity Kalman filter per tracked human id.

State x = (p_x, p_y, v_x, v_y); white-noise acceleration of spectral density
q (m²/s³) drives the velocity; detections measure the position with standard
deviation r (m). Tracks are keyed by the detection id (motion capture gives
stable ids):

- a new id starts a track at its first detection (zero velocity, large
  velocity covariance);
- a frame without that id only predicts, so the covariance grows;
- a track unseen for ``timeout`` seconds is dropped;
- a detection that is not finite, lies outside ``max_range`` or fails the
  innovation gate (Mahalanobis distance² > ``gate``) is rejected and
  counted, and the track only predicts.
"""

from dataclasses import dataclass, field

import numpy as np

_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


@dataclass
class ConstantVelocityKalman:
    """One human's filter."""

    x: np.ndarray
    P: np.ndarray
    acceleration_noise: float
    measurement_noise: float
    last_time: float
    last_seen: float

    @classmethod
    def Start(
        cls,
        position,
        time,
        *,
        acceleration_noise,
        measurement_noise,
        initial_speed_std=1.0,
    ):
        x = np.array([position[0], position[1], 0.0, 0.0], dtype=float)
        P = np.diag([measurement_noise**2] * 2 + [initial_speed_std**2] * 2)
        return cls(
            x=x,
            P=P,
            acceleration_noise=acceleration_noise,
            measurement_noise=measurement_noise,
            last_time=time,
            last_seen=time,
        )

    def Predict(self, time: float) -> None:
        dt = time - self.last_time
        if dt <= 0:
            return
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        q = self.acceleration_noise**2
        Q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        Q = np.zeros((4, 4))
        Q[np.ix_([0, 2], [0, 2])] = Q1
        Q[np.ix_([1, 3], [1, 3])] = Q1
        self.x = F @ self.x
        self.P = F @ self.P @ F.T + Q
        self.last_time = time

    def Innovation(self, z):
        y = np.asarray(z, dtype=float) - _H @ self.x
        S = _H @ self.P @ _H.T + self.measurement_noise**2 * np.eye(2)
        return y, S

    def Update(self, z) -> None:
        y, S = self.Innovation(z)
        K = self.P @ _H.T @ np.linalg.inv(S)
        self.x = self.x + K @ y
        I_KH = np.eye(4) - K @ _H
        # Joseph form: stays symmetric positive definite.
        self.P = (
            I_KH @ self.P @ I_KH.T + K @ (self.measurement_noise**2 * np.eye(2)) @ K.T
        )
        self.last_seen = self.last_time

    @property
    def position(self):
        return self.x[:2].copy()

    @property
    def velocity(self):
        return self.x[2:].copy()


@dataclass
class HumanTracks:
    """All tracked humans (see the module doc)."""

    measurement_noise: float = 0.01
    acceleration_noise: float = 2.0
    timeout: float = 1.0
    max_range: float = 100.0
    gate: float = 100.0  # χ² with 2 dof: 100 is far beyond any honest miss
    tracks: dict = field(default_factory=dict)
    rejected_count: int = 0
    dropped_count: int = 0
    last_frame_time: float = -np.inf

    def Step(self, time: float, detections: dict) -> None:
        """Predicts every track to ``time`` and fuses ``detections``
        ({id: (x, y)})."""
        self.last_frame_time = time
        for track in self.tracks.values():
            track.Predict(time)
        for hid, z in detections.items():
            z = np.asarray(z, dtype=float).reshape(-1)
            if (
                z.size != 2
                or not np.all(np.isfinite(z))
                or np.max(np.abs(z)) > self.max_range
            ):
                self.rejected_count += 1
                continue
            track = self.tracks.get(hid)
            if track is None:
                self.tracks[hid] = ConstantVelocityKalman.Start(
                    z,
                    time,
                    acceleration_noise=self.acceleration_noise,
                    measurement_noise=self.measurement_noise,
                )
                continue
            y, S = track.Innovation(z)
            if y @ np.linalg.solve(S, y) > self.gate:
                self.rejected_count += 1
                continue
            track.Update(z)
        for hid in [
            h for h, t in self.tracks.items() if time - t.last_seen > self.timeout
        ]:
            del self.tracks[hid]
            self.dropped_count += 1

    def Estimates(self, time: float | None = None):
        """(ids, positions (H, 2), velocities (H, 2)) of the live tracks,
        predicted to ``time`` if given (constant velocity)."""
        ids = np.array(sorted(self.tracks), dtype=int)
        pos = np.array(
            [
                self.tracks[h].position
                + (0.0 if time is None else max(0.0, time - self.tracks[h].last_time))
                * self.tracks[h].velocity
                for h in ids
            ]
        ).reshape(-1, 2)
        vel = np.array([self.tracks[h].velocity for h in ids]).reshape(-1, 2)
        return ids, pos, vel
