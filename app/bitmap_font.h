// A 5 x 7 bitmap font of printable ASCII, for the labels of compare's
// contact_sheet.png (issue #37: its SVG had them, the PNG had none). The
// glyphs are drawn here rather than read from a font file, so the sheet is
// the same bytes on every machine and nothing is vendored.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace obscura {

inline constexpr int kGlyphWidth = 5, kGlyphHeight = 7;
inline constexpr int kGlyphAdvance = 6;  // a blank column between glyphs
inline constexpr int kLineAdvance = 10;  // three blank rows between lines

// The 7 rows of a character's glyph, top first, bit 4 the leftmost column.
// Outside printable ASCII (32..126, e.g. the bytes of UTF-8) it is '?'s.
const uint8_t* glyphRows(char c);

// Draws `text` into interleaved RGB8 pixels (width x height, top row first)
// with its first glyph's top-left at (x, y), in `colour`, over what is
// there; nothing at or right of xEnd, nor outside the image.
void drawText(unsigned char* rgb, int width, int height, int x, int y, int xEnd, const std::string& text,
              const unsigned char colour[3]);

// `text` cut into lines of at most `columns` characters (at least one
// line; `columns` below 1 counts as 1).
std::vector<std::string> wrapText(const std::string& text, int columns);

}  // namespace obscura
