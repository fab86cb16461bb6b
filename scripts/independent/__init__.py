"""Helpers of scripts/render_recon_scenes.py: scenes for brdf-rig rendered by Mitsuba 3.

Everything here is written from the formats' definitions (COLMAP, MERL, PLY), not from the
project's Rust code, so that the scenes check the project against an independent reading.
"""
