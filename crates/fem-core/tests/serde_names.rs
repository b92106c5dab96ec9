//! With the `serde` feature, energies and plane models are written and read as the names the
//! command line uses, and an unknown name is rejected with a message listing the valid ones.
#![cfg(feature = "serde")]

use fem_core::PlaneModel;
use fem_core::energy::EnergyKind;

#[test]
fn energy_kind_round_trips_as_its_name() {
    for kind in EnergyKind::ALL {
        let text = serde_json::to_string(&kind).unwrap();
        assert_eq!(text, format!("\"{}\"", kind.name()));
        assert_eq!(serde_json::from_str::<EnergyKind>(&text).unwrap(), kind);
    }
    let e = serde_json::from_str::<EnergyKind>("\"rubber\"").unwrap_err();
    assert!(
        e.to_string().starts_with(
            "unknown energy `rubber` (expected one of: stvk, corotational, neo-hookean, stable-neo-hookean, linear)"
        ),
        "{e}"
    );
}

#[test]
fn plane_model_round_trips_as_its_name() {
    for (model, name) in [
        (PlaneModel::PlaneStrain, "\"plane-strain\""),
        (PlaneModel::PlaneStress, "\"plane-stress\""),
    ] {
        assert_eq!(serde_json::to_string(&model).unwrap(), name);
        assert_eq!(serde_json::from_str::<PlaneModel>(name).unwrap(), model);
    }
    let e = serde_json::from_str::<PlaneModel>("\"plane\"").unwrap_err();
    assert!(
        e.to_string().starts_with("unknown plane model `plane`"),
        "{e}"
    );
}
