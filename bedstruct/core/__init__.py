"""The data model: boxes, frames of spheres, contacts and trajectories."""

from .box import Box
from .contacts import Contacts, WallContacts, lens_radius
from .frame import Frame, Provenance, Units, UNIT_STYLES
from .trajectory import FrameList, Trajectory

__all__ = ["Box", "Frame", "Units", "Provenance", "UNIT_STYLES", "Contacts", "WallContacts",
           "lens_radius", "Trajectory", "FrameList"]
