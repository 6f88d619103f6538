"""Slots of the step tuple ``st`` and columns of its ``contact`` and ``report`` arrays.

See the package docstring for what each holds. Kernels index with these names, never literals.
Each packed layout is declared once, as (name, width) fields in order; the offsets are derived
from it (``columns``), and ``tests/sim/test_compiled.py`` checks the names bound below against
the declaration.
"""


def columns(fields: tuple[tuple[str, int], ...]) -> tuple[int, ...]:
    """The start of each field of a packed row, then the row's width."""
    starts, at = [], 0
    for _, width in fields:
        starts.append(at)
        at += width
    return (*starts, at)


# The step tuple.
X0, Q0, V0, W0 = 0, 1, 2, 3  # the state passed in (read only)
X, Q, V, W = 4, 5, 6, 7  # working state: starts as a copy (q renormalised), ends as the result
FORCE, TORQUE = 8, 9  # applied loads
DISPLACEMENT = 10  # (N, n, 3): zero at the start; the position update adds it to x + Δt v
CONTACT = 11  # (N, C, CONTACT_WIDTH)
REPORT = 12  # (N, REPORT_WIDTH)
STEP_TUPLE_SIZE = 13

# Columns of ``contact``, per slot.
CONTACT_COLUMNS = (
    # written by detection
    ("ARM", 3),  # world vector from the centre of mass to the contact point
    ("GAP", 1),  # signed distance along the normal (< 0: penetration)
    ("BODY", 1),  # body index (float)
    # from here on the columns belong to the contact solve (``contact_*.py``)
    ("JT", 18),  # the contact's rows of J̃ = J M^(-1/2), normal, t₁, t₂, each (linear 3, angular 3)
    ("T1", 3),  # the first tangent t₁ (t₂ = n × t₁)
    ("PATH_GAP", 1),  # the gap where the step's impacts left the contact (the detected gap without)
    ("IMPULSE", 1),  # normal impulse of the step's impacts (the friction budget of the solve)
    ("U1", 6),  # in a body's first slot: its (v, ω) after the velocity update (the energy guard)
    ("PATH_Q", 4),  # in a body's first slot: its orientation along the impacts' path
    # kept between the steps of one call (``steps.carry`` zeroes the columns before WARM only)
    ("WARM", 3),  # the impulse (n, t₁, t₂) the previous step's solve ended with
    ("WARM_OK", 1),  # in slot 0: 1.0 when that solve converged (``SolverSettings.warm_start``)
    # a scene with body–body contacts only (``contact_pairs``); ARM is then body a's arm to
    # the point both bodies take the impulse at (the midpoint of the two features)
    ("NORMAL", 3),  # the rows' normal, from body b to body a (a ground slot's is +z)
    ("ARM_B", 3),  # world vector from body b's centre of mass to that point
    ("JT_B", 18),  # body b's rows of J̃, negated (it takes the opposite impulse), as ``JT``
    # what the detection found (the rows' record: an impact moves the rows from it)
    ("DETECTED_A", 3),  # body a's arm
    ("DETECTED_B", 3),  # body b's arm
    ("DETECTED_NORMAL", 3),
)
(
    ARM,
    GAP,
    BODY,
    JT,
    T1,
    PATH_GAP,
    IMPULSE,
    U1,
    PATH_Q,
    WARM,
    WARM_OK,
    NORMAL,
    ARM_B,
    JT_B,
    DETECTED_A,
    DETECTED_B,
    DETECTED_NORMAL,
    CONTACT_WIDTH,
) = columns(CONTACT_COLUMNS)
GROUND_WIDTH = NORMAL  # the columns of a scene whose contacts are all ground contacts
WARM_END = WARM_OK + 1
SOLVER = JT  # the first column of the contact solve's

# Columns of ``report``, one each (the contact solve's; see ``contacts.stages.ContactReport``).
REPORT_COLUMNS = (
    ("ENGAGED", 1),  # 1.0 if the element had a contact within reach this step
    ("ITERATIONS", 1),  # iterations its solve used
    ("IMPACTS", 1),  # impact events it resolved
    ("CAPPED", 1),  # 1.0 if its solve stopped at a cap instead of converging
    ("UNPAID_ENERGY", 1),  # energy excess (J) the guard could not remove
    ("TOUCHED", 1),  # 1.0 if a contact carried an impulse this step
    (
        "ELAPSED",
        1,
    ),  # scratch, not reported: time into the step of the last impact
    ("NEWTON", 1),  # Newton steps of its solve's polish
    ("WARMED", 1),  # 1.0 if its solve started from the previous step's impulses
    (
        "ENERGY_REMOVED",
        1,
    ),  # energy (J) the contacts took out (``contact_energy``); summed over steps
    # Scratch, not reported: what ``limit_energy`` hands ``separate_contacts``: 1.0 if loads
    # other than gravity act (the separation keeps E − W then), and Σ_b u₁_bᵀ M_b u_b
    # (``energy_removed``).
    ("LOADED", 1),
    ("UPDATE_DOT", 1),
)
(
    ENGAGED,
    ITERATIONS,
    IMPACTS,
    CAPPED,
    UNPAID_ENERGY,
    TOUCHED,
    ELAPSED,
    NEWTON,
    WARMED,
    ENERGY_REMOVED,
    LOADED,
    UPDATE_DOT,
    REPORT_WIDTH,
) = columns(REPORT_COLUMNS)
