"""(being migrated to the new layout)"""
from descent_fmus.synthesis.registry import System

SYSTEM = System(stem="telescope", title="telescope (being migrated)")
