"""The tool and its contact with the part (FORMATS.md "Tool model")."""

from .tool import Tool
from .model import LocalPatch, MeshContact, local_patch, mesh_contact, solve_sink

__all__ = ["Tool", "LocalPatch", "MeshContact", "local_patch", "mesh_contact", "solve_sink"]
