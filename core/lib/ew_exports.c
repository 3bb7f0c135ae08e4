/* The shared library's one translation unit of its own: CMake needs a
 * source per target; every symbol comes from edgewise_core, linked whole. */
typedef int ew_exports_unused;
