"""What every solver's checkpoint shares: the material and contact histories, and the check that
a saved state fits this model and partition."""

from __future__ import annotations

import numpy as np


def histories_state(problem, contact) -> dict[str, np.ndarray]:
    """Material (prefix ``material/``) and contact (``contact/``) histories of this rank."""
    data = {f"material/{k}": v for k, v in problem.material.state_dict().items()}
    if contact is not None:
        data.update({f"contact/{k}": v for k, v in contact.state_dict().items()})
    return data


def load_histories(problem, contact, data: dict[str, np.ndarray]) -> None:
    """Restore :func:`histories_state`."""
    problem.material.load_state({k[9:]: v for k, v in data.items() if k.startswith("material/")})
    if contact is not None:
        contact.load_state({k[8:]: v for k, v in data.items() if k.startswith("contact/")})


def check_layout(data: dict[str, np.ndarray], x, u) -> None:
    """Raise ValueError unless the saved reduced vector and displacement fit ``x`` and ``u``."""
    if data["x"].shape != x.array_r.shape or data["u"].shape != u.x.array.shape:
        raise ValueError(
            f"checkpoint: the solver state does not match this model and partition "
            f"({data['u'].size} local displacement values, this model has {u.x.array.size})"
        )
