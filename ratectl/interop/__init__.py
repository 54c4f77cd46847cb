"""Interoperation with other robotics software: MuJoCo and mink (`ratectl.interop.mujoco`).

Needs the ``mujoco`` extra; nothing else in ratectl imports it.
"""
