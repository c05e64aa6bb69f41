/* The C interface between libgsd and its OpenVDB plugin, libgsd_vdb.so (src/io/vdb_plugin.cpp).
   OpenVDB lives in the plugin, which libgsd loads with dlopen the first time a .vdb is written:
   linked into every gsd program, OpenVDB's relocations cost ~40 ms at each start, which is
   more than a whole `gsd winding` run spends on some inputs. */
#pragma once

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A scalar grid, already validated by gsd::io::write_vdb: node (i, j, k) at lo + (i, j, k)·step,
   values in C order (k fastest). */
struct GsdVdbGrid {
    int nx, ny, nz;
    double lo[3], step[3];
    const float* values;
    const char* name;
    int level_set; /* 1: narrow band of half_width voxels (cubic voxels) */
    double half_width;
    const char* method;  /* "gsd_method" metadata, may be empty */
    const char* creator; /* the grid's creator string */
};

/* Receives the encoded file, possibly in several pieces. */
typedef void (*GsdVdbSink)(void* context, const char* bytes, size_t size);

/* Encodes the grid as a .vdb stream into sink. 0 on success; otherwise nonzero with a message
   in error (error_size bytes, NUL-terminated). */
typedef int (*GsdVdbEncode)(const struct GsdVdbGrid* grid, GsdVdbSink sink, void* context, char* error, size_t error_size);

/* What a decoded grid holds: its nodes, node (i, j, k) at lo + (i, j, k)·step. */
struct GsdVdbDense {
    int nx, ny, nz;
    double lo[3], step[3];
    int level_set;
};

/* Gives the decoder a buffer of nx·ny·nz floats for the grid it describes (C order, k fastest),
   or NULL to refuse it (too large); the refusal's reason stays with the caller. */
typedef float* (*GsdVdbAllocate)(void* context, const struct GsdVdbDense* dense);

/* Reads the file's float grid (the one named "surface" if there are several, else the first)
   into a dense grid over its active voxels' box (grown by one voxel for a level set, whose
   inactive outside and inside then read ± the background). 0 on success; otherwise nonzero with
   a message in error. */
typedef int (*GsdVdbDecode)(const char* path, GsdVdbAllocate allocate, void* context, char* error, size_t error_size);

/* A narrow band on a lattice (a sparse level set): point (i, j, k) at lo + (i, j, k)·voxel. */
struct GsdVdbSparse {
    double lo[3];
    double voxel;
    double half_width; /* in voxels: the background */
    size_t count;
    const int* ijk;      /* 3 per point */
    const float* values; /* 1 per point */
    const char* name;
    const char* method;
    const char* creator;
};

/* Encodes a sparse level set as a .vdb stream: the points active, the rest inactive at
   ±half_width voxels by OpenVDB's signed flood fill. 0 on success. */
typedef int (*GsdVdbEncodeSparse)(const struct GsdVdbSparse* band, GsdVdbSink sink, void* context, char* error, size_t error_size);

/* Receives a triangle mesh: 3 doubles a point, 3 indices a triangle. */
typedef void (*GsdVdbMeshSink)(void* context, const double* points, size_t point_count, const unsigned* triangles,
                               size_t triangle_count);

/* The zero level set of a sparse level set, by OpenVDB's volumeToMesh (quads split in two). */
typedef int (*GsdVdbMeshSparse)(const struct GsdVdbSparse* band, GsdVdbMeshSink sink, void* context, char* error, size_t error_size);

#define GSD_VDB_ENCODE_SYMBOL "gsd_vdb_encode"
#define GSD_VDB_ENCODE_SPARSE_SYMBOL "gsd_vdb_encode_sparse"
#define GSD_VDB_MESH_SPARSE_SYMBOL "gsd_vdb_mesh_sparse"
#define GSD_VDB_DECODE_SYMBOL "gsd_vdb_decode"
#define GSD_VDB_PLUGIN_NAME "libgsd_vdb.so"

#ifdef __cplusplus
}
#endif
