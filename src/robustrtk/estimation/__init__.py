"""robustrtk.estimation"""
