"""robustrtk.pipeline"""
