"""robustrtk.ambiguity"""
