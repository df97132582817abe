//! Anchors known by hardware ids. A third party's log numbers its anchors as the hardware does
//! (11, 12, 4, 9), while the filters index the rows of the anchor table (0..K). [`AnchorIds`]
//! holds the id of each row and turns the ids in a table's anchor columns into rows, with an
//! error that names the id, where it is and the ids there are.

use crate::error::{Error, Result};

/// The hardware id of each row of an anchor table (row `k` has id `ids[k]`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AnchorIds {
    ids: Vec<i64>,
}

impl AnchorIds {
    /// The ids of the anchor rows, in row order: whole numbers, each once.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] (table `anchor ids`) for an id that is not a whole number or is
    /// given twice.
    pub fn new(ids: &[f64]) -> Result<Self> {
        let mut out: Vec<i64> = Vec::with_capacity(ids.len());
        for (row, &id) in ids.iter().enumerate() {
            if !(id.is_finite() && id.fract() == 0.0 && id.abs() < 2f64.powi(53)) {
                return Err(Error::InvalidValue { name: "anchor ids", row, value: id, reason: "an anchor id is a whole number" });
            }
            if out.contains(&(id as i64)) {
                return Err(Error::InvalidValue { name: "anchor ids", row, value: id, reason: "each anchor id is given once" });
            }
            out.push(id as i64);
        }
        Ok(Self { ids: out })
    }

    /// The ids, in row order.
    pub fn ids(&self) -> &[i64] {
        &self.ids
    }

    /// The row of the anchor whose id is `id`, found at row `row` of the table `name`.
    ///
    /// # Errors
    /// [`Error::UnknownAnchorId`] when no anchor has that id.
    pub fn row_of(&self, name: &'static str, row: usize, id: f64) -> Result<usize> {
        self.ids.iter().position(|&k| k as f64 == id).ok_or_else(|| Error::UnknownAnchorId {
            name,
            row,
            id,
            ids: self.ids.iter().map(i64::to_string).collect::<Vec<_>>().join(", "),
        })
    }

    /// Rewrites the anchor columns `columns` of every row of the table `name` from ids to rows.
    ///
    /// # Errors
    /// As [`AnchorIds::row_of`], for the first id that is no anchor's.
    pub fn to_rows<R: AsMut<[f64]>>(&self, name: &'static str, rows: &mut [R], columns: &[usize]) -> Result<()> {
        for (row, values) in rows.iter_mut().enumerate() {
            let values = values.as_mut();
            for &c in columns {
                if let Some(v) = values.get_mut(c) {
                    *v = self.row_of(name, row, *v)? as f64;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_become_rows_and_an_unknown_id_says_which_there_are() {
        let ids = AnchorIds::new(&[11.0, 12.0, 4.0, 9.0]).expect("ids");
        let mut ranges = vec![[0.1, 4.0, 3.2], [0.1, 11.0, 5.0], [0.2, 9.0, 1.0]];
        ids.to_rows("ranges", &mut ranges, &[1]).expect("known ids");
        assert_eq!(ranges.iter().map(|r| r[1]).collect::<Vec<_>>(), [2.0, 0.0, 3.0]);
        let mut bad = vec![[0.1, 4.0, 3.2], [0.3, 7.0, 1.0]];
        let e = ids.to_rows("ranges", &mut bad, &[1]).unwrap_err().to_string();
        assert!(e.contains("anchor id 7 at row 1") && e.contains("11, 12, 4, 9") && e.contains("map ids to rows"), "{e}");
        for wrong in [[1.0, 1.0], [1.5, 2.0], [f64::NAN, 1.0]] {
            assert!(AnchorIds::new(&wrong).is_err(), "{wrong:?}");
        }
    }
}
