"""robustrtk.geometry"""
