"""Baseline methods the paper's method is compared with (registered in ikbench.methods)."""
