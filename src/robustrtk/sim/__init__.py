"""robustrtk.sim"""
