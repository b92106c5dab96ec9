//! Library tests of fem-cases, in one test binary: the claims of the paper's Section 4 on the
//! built-in cases, and the golden summaries.

mod budget;
mod budget3;
mod cases;
mod compare;
mod figures;
mod goldens;
mod scene;
mod vtk;
