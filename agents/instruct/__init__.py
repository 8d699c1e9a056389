"""Instruction following with a language planner in the loop: the planner interface
(``agents.instruct.planner``: what a planner is told and answers, ``make_planner``), its backends
(``offline``, the default that ships; ``chat``, an OpenAI-compatible chat-completions server) and
the agents that use it (``agents.instruct.agent``).
"""
