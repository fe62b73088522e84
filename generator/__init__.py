"""The kollagen engine: a bit-exact numpy re-implementation of kollagen's generator (no I/O)."""

from generator.config import AgentConfig, InterLoopClosureConfig, SynthConfig
from generator.kollagen import SynthOutput, generate

__all__ = ["AgentConfig", "InterLoopClosureConfig", "SynthConfig", "SynthOutput", "generate"]
