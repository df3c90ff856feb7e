"""robustrtk.measurement"""
