//! A fixed split of an acquisition cross-validation (`--test`): the held-out materials by
//! name.

use super::*;

/// The held-out materials of a fixed split (`--test`), by name, as increasing collection
/// indices; `None` for none given. Refused: a name the collection does not have, a name
/// listed twice.
pub(super) fn test_split(
    coll: &Collection,
    test: &[String],
) -> Result<Option<Vec<usize>>, AcquireError> {
    if test.is_empty() {
        return Ok(None);
    }
    let names = coll.names();
    let mut idx = Vec::with_capacity(test.len());
    for (j, t) in test.iter().enumerate() {
        let Some(i) = names.iter().position(|x| x == t) else {
            return Err(AcquireError::InvalidParam {
                name: "test",
                value: t.clone(),
                expected: format!(
                    "names of the collection's materials (`{t}` is not one of its {})",
                    names.len()
                ),
            });
        };
        if test[..j].contains(t) {
            return Err(AcquireError::InvalidParam {
                name: "test",
                value: t.clone(),
                expected: "each held-out material once".into(),
            });
        }
        idx.push(i);
    }
    idx.sort_unstable();
    Ok(Some(idx))
}
