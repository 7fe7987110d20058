//! Energy compensation: albedo tables, multiple-scattering lobe, furnace checks.
