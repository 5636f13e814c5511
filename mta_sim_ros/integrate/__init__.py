"""One stepping interface over fixed-step Runge-Kutta methods and scipy's adaptive solvers."""
from .steppers import ADAPTIVE_METHODS, FIXED_METHODS, METHODS, IntegrationError, make_stepper

__all__ = ["ADAPTIVE_METHODS", "FIXED_METHODS", "METHODS", "IntegrationError", "make_stepper"]
