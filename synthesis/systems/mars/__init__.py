"""(being migrated to the new layout)"""
from descent_fmus.synthesis.registry import System

SYSTEM = System(stem="mars", title="mars (being migrated)")
