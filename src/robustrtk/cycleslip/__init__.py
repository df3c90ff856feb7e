"""robustrtk.cycleslip"""
