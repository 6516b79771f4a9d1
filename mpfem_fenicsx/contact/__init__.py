"""Contact between particles: search, laws (penalty, adhesion, friction), history, assembly."""

from .laws import ContactLaw
from .model import ContactModel
from .search import ContactPoints, ContactSearch
from .surface import ContactSurface

__all__ = ["ContactLaw", "ContactModel", "ContactPoints", "ContactSearch", "ContactSurface"]
