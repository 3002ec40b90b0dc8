"""The tool and its contact with the part (FORMATS.md "Tool model")."""

from .model import LocalPatch, MeshContact, local_patch, mesh_contact, solve_sink
from .tool import Tool

__all__ = ["Tool", "LocalPatch", "MeshContact", "local_patch", "mesh_contact", "solve_sink"]
