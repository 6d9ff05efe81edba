"""Hypothesis-generated MJCF fragments around default classes, and the properties that check a loader on them.

Strategies (`documents`, `broken_documents`, `kinematic_trees`) draw valid-or-rejected MJCF documents; the
properties (`check_document`, `assert_conforms`) compare the loader with MuJoCo through the harness's tiers;
`CORNER_CASES` are the documented default-class corner cases; shrunk counterexamples go to
`corpus/regressions/`. `python -m conformance.fragments --examples N` fuzzes and prints the throughput.
"""

from .corner_cases import CORNER_CASES, CornerCase
from .document import Body, DefaultClass, Document, Element, MeshAsset, RawDocument, write
from .properties import Outcome, assert_conforms, check_document, check_path
from .strategies import broken_documents, documents, kinematic_trees
from .tally import Tally

__all__ = [
    "CORNER_CASES",
    "Body",
    "CornerCase",
    "DefaultClass",
    "Document",
    "Element",
    "MeshAsset",
    "Outcome",
    "RawDocument",
    "Tally",
    "assert_conforms",
    "broken_documents",
    "check_document",
    "check_path",
    "documents",
    "kinematic_trees",
    "write",
]
