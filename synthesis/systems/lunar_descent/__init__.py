"""(being migrated to the new layout)"""
from descent_fmus.synthesis.registry import System

SYSTEM = System(stem="lunar_descent", title="lunar_descent (being migrated)")
