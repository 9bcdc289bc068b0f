"""Command-line options shared by several commands (``demo``, ``export``)."""

from __future__ import annotations

import argparse


def model_file_options(parser: argparse.ArgumentParser, use_pca_default: str) -> None:
    """``--ext`` and ``--use-pca/--no-use-pca``, as smplx's ``ext`` and ``use_pca``; ``use_pca_default`` says
    what the command does without ``--use-pca``."""
    parser.add_argument(
        "--ext",
        choices=("pkl", "npz"),
        default=None,
        help="model file format to look for first in a folder (default: smplx's, npz for SMPL-X, pkl for the "
        "others); the other format is used when only it is there",
    )
    parser.add_argument(
        "--use-pca",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"SMPL+H / SMPL-X: hand poses as PCA coefficients (default: {use_pca_default})",
    )
