"""robustrtk.cli"""
