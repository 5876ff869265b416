//! The keys of each object in a paper scene: those the importer reads, those it ignores (with
//! the reason, for the scene's notes) and those it cannot simulate yet. Any other key is an
//! error naming it.

/// The top-level keys.
pub(super) const TOP_KEYS: &[&str] = &["Parameters", "Friction coefficients", "Meshes", "Obstacles", "Clothes"];
/// The keys of `"Parameters"[0]` that are read.
pub(super) const PARAM_USED: &[&str] = &[
    "Self-collision",
    "Simulation HZ",
    "Gravity",
    "Is underwater",
    "Handle collision",
    "Max Iteration",
    "Damping coefficient",
];
/// The keys of `"Parameters"[0]` that are ignored, with the reason.
pub(super) const PARAM_IGNORED: &[(&str, &str)] = &[
    (
        "Self-collision tolerance",
        "not read by the reference implementation (its arcsim contact thickness is 1e-4); contacts between bodies keep 1e-3 m apart (CLOTH_THICKNESS)",
    ),
    ("Air damping", "air drag is not simulated"),
    ("Frame number", "not read by the reference implementation"),
    ("LocalGlobal", "not read by the reference implementation"),
    ("Signal", "not read by the reference implementation"),
    ("Type", "not read by the reference implementation"),
    ("Steps per frame", "not read by the reference implementation"),
    ("GravityY", "not read by the reference implementation (use \"Gravity\")"),
    (
        "World Alpha",
        "contact relaxation of the reference's self-collision loop",
    ),
    ("World Friction", "friction of the reference's self-collision loop"),
    (
        "Is skeleton actuated",
        "selects the reference's action interface (joint torques come from a controller)",
    ),
];
/// The keys of a `"Meshes"` entry that are read.
pub(super) const MESH_USED: &[&str] = &[
    "Obj filename",
    "Scale",
    "Mass",
    "Youngs Modulus",
    "Poisson Ratio",
    "Attach Verts",
    "Attach Stiffness",
    "Enable Gravity",
    "Is Mass Same",
    "Bones",
    "Volume Verts",
    "Muscle filename",
    "Muscle Stiffness",
];
/// The keys of a `"Meshes"` entry that are ignored, with the reason.
pub(super) const MESH_IGNORED: &[(&str, &str)] = &[
    (
        "Friction coefficients",
        "the reference implementation ignores per-mesh friction",
    ),
    ("Actuator type", "selects the reference's action interface"),
    ("Center Index", "used by the reference's controllers only"),
    ("End Effector Index", "used by the reference's controllers only"),
    ("Local Contour Index", "used by the reference's controllers only"),
    ("Type", "always \"Soft Articulated\""),
    ("Material Identifier", "not used by the solver"),
    ("Attach y", "not read by the reference implementation"),
    (
        "Sampling filename",
        "vertex samples for the reference's controller observations (the file is not in its data either)",
    ),
];
/// The keys of a `"Meshes"` entry that cannot be simulated yet, with the feature they need.
pub(super) const MESH_UNSUPPORTED: &[(&str, &str)] = &[];
/// The keys of an `"Obstacles"` entry (all read or deliberately not read, as in the reference).
pub(super) const OBSTACLE_KEYS: &[&str] = &["Obj filename", "Scale", "Collision tolerance"];
/// The keys of a `"Clothes"` entry that are read.
pub(super) const CLOTH_USED: &[&str] = &[
    "Obj filename",
    "Scale",
    "Area Density",
    "Bending",
    "Stretching",
    "Attach Stiffness",
    "Attach Verts",
];
/// The keys of a `"Clothes"` entry that are ignored, with the reason.
pub(super) const CLOTH_IGNORED: &[(&str, &str)] = &[
    (
        "Friction coefficients",
        "per-body friction; contacts between bodies use the top-level \"Friction coefficients\"",
    ),
    ("Material Identifier", "not used by the solver"),
];
