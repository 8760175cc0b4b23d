"""An independent computation of the compass gait's period-one gait, without Pinocchio or legsim:
the reference of the walker and ``legsim orbit`` tests.

The equations of motion of the three point masses are written out by hand (M = sum m J^T J,
with the centripetal terms of each mass), the plastic heel strike is an impulse on a floating
model with the hip free, a step is integrated by scipy's DOP853 (rtol = atol = 1e-12) with a
terminal event, and the fixed point is solved by scipy's fsolve; the multipliers are the
eigenvalues of the step map's Jacobian by central differences (~1e-7 accurate). Angles are the
legs' leans from the slope normal (positive with the hip downhill of the foot), theta1 the
stance leg, theta2 the swing leg.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

#: The standard parameters of Goswami, Thuilot & Espiau: masses (kg), leg segments (m),
#: gravity (m/s^2), slope (degrees).
STANDARD = {"m": 5.0, "mH": 10.0, "a": 0.5, "b": 0.5, "g": 9.81, "slope": 3.0}


class PointMassCompassGait:
    def __init__(self, m, mH, a, b, g, slope):
        self.m, self.mH, self.a, self.b = m, mH, a, b
        self.l = a + b
        s = math.radians(slope)
        self.gvec = g * np.array([math.sin(s), -math.cos(s)])

    def rhs(self, t, x):
        t1, t2, w1, w2 = x
        m, mH, a, b, leg = self.m, self.mH, self.a, self.b, self.l
        u1, u2 = np.array([math.sin(t1), math.cos(t1)]), np.array([math.sin(t2), math.cos(t2)])
        d1, d2 = np.array([math.cos(t1), -math.sin(t1)]), np.array([math.cos(t2), -math.sin(t2)])
        z = np.zeros(2)
        # (mass, Jacobian of its position wrt (theta1, theta2), J-dot times the rates)
        parts = [
            (m, np.column_stack([a * d1, z]), -a * u1 * w1**2),
            (mH, np.column_stack([leg * d1, z]), -leg * u1 * w1**2),
            (m, np.column_stack([leg * d1, -b * d2]), -leg * u1 * w1**2 + b * u2 * w2**2),
        ]
        M = sum(mi * J.T @ J for mi, J, _ in parts)
        f = sum(mi * J.T @ (self.gvec - jd) for mi, J, jd in parts)
        return np.concatenate([[w1, w2], np.linalg.solve(M, f)])

    def heel_strike(self, x):
        t1, t2, w1, w2 = x
        m, mH, b, leg = self.m, self.mH, self.b, self.l
        d1, d2 = np.array([math.cos(t1), -math.sin(t1)]), np.array([math.cos(t2), -math.sin(t2)])
        I2, z = np.eye(2), np.zeros(2)
        # Floating coordinates (hip x, hip z, theta1, theta2); masses at hip - b u_i and the hip.
        parts = [
            (m, np.column_stack([I2, -b * d1, z])),
            (mH, np.column_stack([I2, z, z])),
            (m, np.column_stack([I2, z, -b * d2])),
        ]
        M = sum(mi * J.T @ J for mi, J in parts)
        J2 = np.column_stack([I2, z, -leg * d2])  # the swing foot hip - leg u2
        v = np.concatenate([leg * w1 * d1, [w1, w2]])
        Mi = np.linalg.inv(M)
        vp = v - Mi @ J2.T @ np.linalg.solve(J2 @ Mi @ J2.T, J2 @ v)
        return np.array([t2, t1, vp[3], vp[2]])

    def step(self, x0):
        def strike(t, x):  # swing foot height, counted only in front of the stance foot
            return self.l * (math.cos(x[0]) - math.cos(x[1])) if x[1] < x[0] else 1.0

        strike.terminal, strike.direction = True, -1
        sol = solve_ivp(self.rhs, (0.0, 5.0), x0, method="DOP853", rtol=1e-12, atol=1e-12, events=strike)
        return self.heel_strike(sol.y_events[0][0]), float(sol.t_events[0][0])

    def gait(self, guess=(-0.27, 1.09, 0.38)):
        def F(z):
            x1, _ = self.step(np.array([z[0], -z[0], z[1], z[2]]))
            return x1[[0, 2, 3]] - z

        z = fsolve(F, guess, xtol=1e-13)
        x0 = np.array([z[0], -z[0], z[1], z[2]])
        _x1, period = self.step(x0)
        J = np.zeros((3, 3))
        for j in range(3):
            dz = np.zeros(3)
            dz[j] = 1e-6
            J[:, j] = (F(z + dz) - F(z - dz)) / 2e-6 + (np.arange(3) == j)
        mu = np.linalg.eigvals(J)
        return {
            "x": x0,
            "period": period,
            "step": 2 * self.l * math.sin(-z[0]),
            "residual": np.max(np.abs(F(z))),
            "multipliers": mu[np.argsort(-np.abs(mu), kind="stable")],
        }
