//! Reading and writing DEM files (being implemented).
