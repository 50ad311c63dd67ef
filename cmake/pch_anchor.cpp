// The one translation unit of the targets that compile the shared precompiled headers
// (cmake/precompiled_headers.cmake); nothing links it.
