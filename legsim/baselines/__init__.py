"""Baselines legsim is compared against: the Paoli-Schatzman scheme (paper 000 eq. (29)) and an
event-driven simulator on scipy's solve_ivp, each made as fast as legsim's own core."""

from .event_driven import simulate_events
from .paoli_schatzman import paoli_schatzman

__all__ = ["paoli_schatzman", "simulate_events"]
