"""(being migrated to the new layout)"""
from descent_fmus.synthesis.registry import System

SYSTEM = System(stem="lunar_landing", title="lunar_landing (being migrated)")
