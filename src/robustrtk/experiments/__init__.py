"""End-to-end reproductions of published experiments on simulated data."""

from robustrtk.experiments.li2019 import Report, run_li2019

__all__ = ["Report", "run_li2019"]
