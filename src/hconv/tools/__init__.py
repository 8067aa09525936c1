"""Layer 4, tools: what hconv's commands do besides converting (diagnose, compare, stability,
bench, generate) and what they share (analytic scenes, streaming summaries).
"""
