"""Command-line subcommand (registered by :mod:`smplcore.cli`)."""

from __future__ import annotations

import argparse


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register this module's subcommand (none yet)."""
