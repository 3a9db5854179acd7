//! `hdrcodec-tests`: a package of tests and benches only. Its integration tests (the `.rs`
//! files beside this one) check the family across crates and against the reference
//! implementations; `../benches` measures it against the peers. Nothing here is a library.

#![forbid(unsafe_code)]
