"""Instruction following with a language planner in the loop (issue 43): the planner interface
(``agents.instruct.planner``: what a planner is told and answers, ``make_planner``) and its
backends (``offline``; ``chat``, an OpenAI-compatible chat-completions server).
"""
