//! TODO(geometry helper G2b): IGES 5.3 and STEP AP214 export
