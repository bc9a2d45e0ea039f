//! Every stage's views, by stage in the frame's order ([`stages::views`]): what the display
//! pass's names are checked against (a configuration's `display.mode`, `--display`, an
//! experiment's `display_modes`) and the viewer's menu is made from. A view is declared in its
//! stage's file only (its `VIEWS`).

use std::str::FromStr;

use serde::{Deserialize, Deserializer};

use super::display::{DisplayMode, View};
use super::stages;

/// Every view with its stage's name, in the frame's order.
pub fn all() -> impl Iterator<Item = (&'static str, &'static View)> {
    stages::views()
        .iter()
        .flat_map(|(stage, views)| views.iter().map(move |v| (*stage, v)))
}

/// The view named `name`, with its stage's name.
pub fn find(name: &str) -> Option<(&'static str, &'static View)> {
    all().find(|(_, v)| v.name == name)
}

/// Every view's name, in the frame's order.
pub fn names() -> Vec<&'static str> {
    all().map(|(_, v)| v.name).collect()
}

impl FromStr for DisplayMode {
    type Err = String;

    /// A view's name; an error listing them all for any other.
    fn from_str(s: &str) -> Result<Self, String> {
        match find(s) {
            Some((_, v)) => Ok(DisplayMode::named(v.name)),
            None => Err(format!(
                "unknown display mode `{s}`; one of {}",
                names().join(", ")
            )),
        }
    }
}

impl<'de> Deserialize<'de> for DisplayMode {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_parse_back() {
        let names = names();
        for (i, n) in names.iter().enumerate() {
            assert!(!names[i + 1..].contains(n), "{n} twice");
            let m: DisplayMode = n.parse().unwrap();
            assert_eq!(m.name(), *n);
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{n}\""));
            assert_eq!(serde_json::from_str::<DisplayMode>(&json).unwrap(), m);
        }
        assert!("nope"
            .parse::<DisplayMode>()
            .unwrap_err()
            .contains("bounce-albedo"));
        assert!(serde_json::from_str::<DisplayMode>("\"nope\"").is_err());
        assert_eq!(DisplayMode::FINAL.name(), "final");
        assert!(find("final").is_some());
    }
}
