#include "pm/io/volume_io.h"

#include <cmath>
#include <filesystem>
#include <sstream>
#include <utility>
#include <vector>

#include "pm/base/atomic_file.h"
#include "pm/base/error.h"
#include "pm/io/inr.h"
#include "pm/io/metaimage.h"
#include "pm/io/nifti.h"
#include "pm/io/nrrd.h"
#include "pm/io/vdb.h"
#include "pm/io/volume_header.h"

namespace fs = std::filesystem;

namespace pm {
namespace {

enum class Format { nrrd, nhdr, vdb, mha, mhd, nifti, inr, unknown };

Format format_of(const std::string& path) {
  const std::string e = file_extension(path);
  if (e == ".nrrd") return Format::nrrd;
  if (e == ".nhdr") return Format::nhdr;
  if (e == ".vdb") return Format::vdb;
  if (e == ".mha") return Format::mha;
  if (e == ".mhd") return Format::mhd;
  if (e == ".nii" || e == ".nii.gz") return Format::nifti;
  if (e == ".inr" || e == ".inr.gz") return Format::inr;
  return Format::unknown;
}

[[noreturn]] void unknown_extension(const std::string& who, const std::string& path) {
  const std::string e = file_extension(path);
  throw UsageError(who + ": " + quote(path) + ": unknown volume file extension " +
                   (e.empty() ? std::string("(none)") : quote(e)) +
                   "; expected one of " + volume_extensions());
}

std::string prefixed(const std::string& who, const char* what) {
  const std::string w(what);
  return w.rfind(who + ":", 0) == 0 ? w : who + ": " + w;
}

}  // namespace

bool is_volume_path(const std::string& path) { return format_of(path) != Format::unknown; }

std::string volume_extensions() { return ".nrrd .nhdr .vdb .mha .mhd .nii .nii.gz .inr .inr.gz"; }

Volume read_volume(const std::string& path) {
  const std::string who = "read_volume";
  const Format f = format_of(path);
  if (f == Format::unknown) unknown_extension(who, path);
  try {
    require_readable(path);
  } catch (const IoError& e) {
    throw IoError(prefixed(who, e.what()));
  }
  Volume v;
  switch (f) {
    case Format::nrrd:
    case Format::nhdr: v = read_nrrd(path); break;
    case Format::vdb: v = read_vdb(path); break;
    case Format::mha:
    case Format::mhd: v = read_metaimage(path); break;
    case Format::nifti: v = read_nifti(path); break;
    case Format::inr: v = read_inr(path); break;
    case Format::unknown: break;
  }
  // Every reader checks this before allocating; repeated here so no format can
  // hand back a volume that breaks the invariants.
  check_volume_header(who, path, v.dims(), v.geometry());
  return v;
}

void write_volume(const Volume& v, const std::string& path, const VolumeWriteParams& p) {
  const std::string who = "write_volume";
  const Format f = format_of(path);
  if (f == Format::unknown) unknown_extension(who, path);
  if (v.empty()) throw InputError(who + ": " + quote(path) + ": the volume is empty; nothing to write");
  // Writers name the temporary files they are given; messages name the target.
  std::vector<std::pair<std::string, std::string>> temp_names;
  const auto fix = [&](const char* what) {
    std::string m = prefixed(who, what);
    for (const auto& [tmp, target] : temp_names)
      for (std::size_t at = 0; (at = m.find(tmp, at)) != std::string::npos; at += target.size())
        m.replace(at, tmp.size(), target);
    return m;
  };
  try {
    if (f == Format::nhdr || f == Format::mhd) {
      // Header + data file: both are written under temporary names, the header
      // already naming the final data file; the data file is renamed into
      // place first, then the header.
      const std::string data =
          f == Format::nhdr ? nhdr_data_path(path, p.compress) : mhd_data_path(path, p.compress);
      const std::string data_name = fs::path(data).filename().string();
      AtomicFile data_file(data);
      AtomicFile header(path);
      temp_names = {{data_file.temp_path(), data}, {header.temp_path(), path}};
      if (f == Format::nhdr)
        write_nrrd_detached(v, header.temp_path(), data_file.temp_path(), data_name, p.compress);
      else
        write_metaimage_detached(v, header.temp_path(), data_file.temp_path(), data_name, p.compress);
      data_file.commit();
      header.commit();
      return;
    }
    AtomicFile out(path);
    temp_names = {{out.temp_path(), path}};
    switch (f) {
      case Format::nrrd: write_nrrd(v, out.temp_path(), p.compress); break;
      case Format::vdb: write_vdb(v, out.temp_path()); break;
      case Format::mha: write_metaimage(v, out.temp_path(), p.compress); break;
      case Format::nifti: write_nifti(v, out.temp_path()); break;
      case Format::inr: write_inr(v, out.temp_path()); break;
      default: break;
    }
    out.commit();
  } catch (const IoError& e) {
    throw IoError(fix(e.what()));
  } catch (const InputError& e) {
    throw InputError(fix(e.what()));
  }
}

}  // namespace pm
