//! footscan fleet: scans from many scanners in one PostgreSQL.
