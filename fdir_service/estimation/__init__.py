"""Estimation core: the thesis's filter family built from composable parts (SPEC sections 5-6)."""
