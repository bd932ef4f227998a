#pragma once
// MetaImage (.mha single file, .mhd + .raw/.zraw), parsed by hand.
// Reads NDims = 3 images of MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT,
// MET_UINT, MET_INT, MET_ULONG_LONG, MET_LONG_LONG, MET_FLOAT or MET_DOUBLE,
// one channel, raw or CompressedData (zlib or gzip stream), either byte order.
// Geometry: Offset (or Position / Origin) is the world position of voxel 0;
// the direction of axis a is TransformMatrix (or Rotation / Orientation)
// elements [3a, 3a+2], normalised and scaled by ElementSpacing (or
// ElementSize) of that axis. World coordinates are LPS, as ITK writes them
// (libcore's frame, pm/base/volume.h). AnatomicalOrientation (ITK's code: a
// letter per axis naming the side it comes from, "RAI" = +x +y +z in LPS)
// gives the directions when there is no TransformMatrix; with one, the matrix
// wins and a code that disagrees is reported with pm::warn.
// HeaderSize applies to separate data files (-1: the data end the file).
// CompressedDataSize is only checked against the file size: the data are
// inflated from all bytes that follow (some writers understate it).
// Writes little/native byte order, TransformMatrix, Offset,
// AnatomicalOrientation (the code closest to the directions), ElementSpacing.
#include <string>

#include "pm/base/volume.h"

namespace pm {
Volume read_metaimage(const std::string& path);
/// .mha: header and voxels in one file. .mhd: the voxels go to "<stem>.zraw"
/// (zlib, compress) or "<stem>.raw" beside the header.
void write_metaimage(const Volume& v, const std::string& path, bool compress = true);
/// .mhd pair: the header goes to `header_path` and names `data_name` (relative
/// to the header's folder) as its ElementDataFile; the voxels go to
/// `data_path`. Used by write_volume for atomic pairs (see write_nrrd_detached).
void write_metaimage_detached(const Volume& v, const std::string& header_path,
                              const std::string& data_path, const std::string& data_name,
                              bool compress = true);
/// The data file write_metaimage puts beside a .mhd: "<dir>/<stem>.zraw" or "<dir>/<stem>.raw".
std::string mhd_data_path(const std::string& header_path, bool compress);
}  // namespace pm
