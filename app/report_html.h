// DIR/report.html of `obscura compare` (docs/compare.md "The report page"):
// one page a browser opens from disk, with the plot, the table, the verdicts
// and a viewer of each cell's pass against the reference, decoded from the
// float data written beside it in DIR/report_data/.
#pragma once

#include <string>

#include "app/report.h"

namespace obscura {

// Writes report.html and report_data/ into r.dir. `resultsJson` is the text
// of results.json (embedded: the page needs no request), `plotSvg` the
// error-versus-time plot (its points carry data-cell = the cell's index).
// Throws obscura::Error naming a file it cannot write.
void writeReportHtml(const CompareReport& r, const std::string& resultsJson, const std::string& plotSvg);

// The float data of one image for the page: un-premultiplied R, G, B and a
// mask (1 where the pixel is compared) per pixel, row-major, downsampled by
// `factor` (box average), as little-endian float32 in base64. A pixel is
// compared where `mask` holds (PassImage::a of the reference is 1 and, for a
// pass, its own A is above 0: comparedPixels).
std::string reportImageBase64(const PassImage& img, const PassImage& ref, bool isReference, int factor);

// "ab+/": base64 (RFC 4648, with '=' padding).
std::string base64(const unsigned char* data, size_t n);

}  // namespace obscura
