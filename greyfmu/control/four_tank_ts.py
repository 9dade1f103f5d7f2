"""Table 1's Takagi–Sugeno model of the four-tank levels h_1, h_2 (Pan, Shen & Luh 2012, seed 003, §5.1).

Consequents are Table 1's, in the regressor order x = [h_j(k−1), h_3(k−1), h_4(k−1)] plus the
affine term.  The paper gives no antecedent sets Ω_i, so they are OUR RECONSTRUCTION: rule i
is centred where the map (41)–(42) has Table 1's local pole a_i on the self term,
1 − 1.41/√h = a_i, i.e. h* = (1.41/(1 − a_i))², for h_1 (from the h_1 rule) and h_2 (from the
h_2 rule); h_3 and h_4 get the same centres as h_1 and h_2 (at equilibrium √h_1 ≈ √h_3 when the
inputs are equal); all widths are ``WIDTH``.
"""

from __future__ import annotations

import numpy as np

from greyfmu.control.ts_fuzzy import Antecedent, TSModel

TABLE1_H1 = np.array([[0.411, 0.653, 0.0774, -0.0211], [0.57, 0.3, 0.176, -0.0008], [0.74, 0.186, 0.099, -0.0091]])
"""Table 1, h_1(k) = a h_1(k−1) + b h_3(k−1) + c h_4(k−1) + d, rules R_1..R_3."""
TABLE1_H2 = np.array([[0.176, 0.0843, 0.873, -0.0049], [0.596, 0.108, 0.317, -0.0256], [0.717, 0.118, 0.175, -0.0101]])
"""Table 1, h_2(k) = a h_2(k−1) + b h_3(k−1) + c h_4(k−1) + d, rules R_1..R_3."""
WIDTH = 6.0


def table1_antecedent() -> Antecedent:
    """Reconstructed Ω_1..Ω_3 on z = [h_1, h_2, h_3, h_4](k−1) (see the module docstring)."""
    h1 = (1.41 / (1.0 - TABLE1_H1[:, 0])) ** 2
    h2 = (1.41 / (1.0 - TABLE1_H2[:, 0])) ** 2
    centres = np.column_stack([h1, h2, h1, h2])
    return Antecedent.from_widths(centres, np.full_like(centres, WIDTH))


def table1_model(output: int) -> TSModel:
    """Table 1's TS model of h_1 (output 1) or h_2 (output 2); regressor [h_output, h_3, h_4](k−1)."""
    if output not in (1, 2):
        raise ValueError(f"table1_model: output must be 1 or 2, got {output}")
    return TSModel(table1_antecedent(), (TABLE1_H1 if output == 1 else TABLE1_H2).copy())


def regressor(h_previous: np.ndarray, output: int) -> np.ndarray:
    """x = [h_output, h_3, h_4](k−1) from the four levels at k−1."""
    return np.array([h_previous[output - 1], h_previous[2], h_previous[3]])
