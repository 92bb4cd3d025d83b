//! Reading a store table column by column, for the audit and the report: a null where the
//! table holds none is an error naming the column.

use polars::prelude::*;

fn missing(name: &str) -> PolarsError {
    PolarsError::NoData(format!("a null in column {name}").into())
}

pub fn strings(frame: &DataFrame, name: &str) -> PolarsResult<Vec<String>> {
    optional_strings(frame, name)?
        .into_iter()
        .map(|v| v.ok_or_else(|| missing(name)))
        .collect()
}

pub fn optional_strings(frame: &DataFrame, name: &str) -> PolarsResult<Vec<Option<String>>> {
    Ok(frame
        .column(name)?
        .str()?
        .iter()
        .map(|v| v.map(str::to_owned))
        .collect())
}

pub fn optional_u32s(frame: &DataFrame, name: &str) -> PolarsResult<Vec<Option<u32>>> {
    Ok(frame.column(name)?.u32()?.iter().collect())
}

pub fn u32s(frame: &DataFrame, name: &str) -> PolarsResult<Vec<u32>> {
    optional_u32s(frame, name)?
        .into_iter()
        .map(|v| v.ok_or_else(|| missing(name)))
        .collect()
}

pub fn f64s(frame: &DataFrame, name: &str) -> PolarsResult<Vec<f64>> {
    let column = frame.column(name)?.cast(&DataType::Float64)?;
    column
        .f64()?
        .iter()
        .map(|v| v.ok_or_else(|| missing(name)))
        .collect()
}
