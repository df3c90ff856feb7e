"""robustrtk.eval"""
