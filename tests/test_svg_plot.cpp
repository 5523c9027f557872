// The shared SVG figure writer (libcore svg_plot): structure, ticks, log axes, the y = x line, gaps.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "blt/core/error.hpp"
#include "blt/core/svg_plot.hpp"
#include "svg_check.hpp"

using namespace blt;

TEST_CASE("svg plot: one element per series point, open markers where asked, labelled axes, legend") {
  svg::Series measured;
  measured.label = "measured";
  measured.x = {1, 2, 3};
  measured.y = {2, 4, 6};
  measured.open = {false, true, false};
  measured.tooltips = {"a", "b <c>", "d"};
  svg::Series model;
  model.label = "model";
  model.style = svg::Style::line;
  model.x = {0, 3};
  model.y = {0, 6};
  svg::PlotOptions o;
  o.title = "T & t";
  o.xLabel = "x (mm)";
  o.yLabel = "y (km/s)";
  o.markerLegend.push_back({"stopped", "white", "#333"});
  const std::string text = svg::renderSvg({{}, {measured, model}, o});
  std::string problem;
  CHECK_MESSAGE(wellFormed(text, problem), problem);
  CHECK(countOf(text, "<circle class=\"point\"") == 3);
  CHECK(countOf(text, "fill=\"white\" stroke=\"#0072B2\"") == 1);  // the one open marker
  CHECK(countOf(text, "<path class=\"curve\"") == 1);
  CHECK(text.find(">x (mm)</text>") != std::string::npos);
  CHECK(text.find(">y (km/s)</text>") != std::string::npos);
  CHECK(text.find("T &amp; t") != std::string::npos);
  CHECK(text.find("<title>b &lt;c&gt;</title>") != std::string::npos);
  CHECK(text.find(">measured</text>") != std::string::npos);
  CHECK(text.find(">model</text>") != std::string::npos);
  CHECK(text.find(">stopped</text>") != std::string::npos);
  // Linear ticks on 0..3 (x) are 1-2-5 steps: 0, 0.5, ..., 3.
  CHECK(text.find(">2.5</text>") != std::string::npos);
}

TEST_CASE("svg plot: log axes tick at decades and skip non-positive and non-finite points, y = x spans both") {
  svg::Series s;
  s.x = {0.01, 0.1, 1, 10, -1, std::numeric_limits<double>::quiet_NaN()};
  s.y = {0.02, 0.2, 2, 20, 5, 5};
  svg::PlotOptions o;
  o.logX = o.logY = true;
  o.identityLine = true;
  const std::string text = svg::renderSvg({{}, {s}, o});
  std::string problem;
  CHECK_MESSAGE(wellFormed(text, problem), problem);
  CHECK(countOf(text, "<circle class=\"point\"") == 4);
  CHECK(countOf(text, "<line class=\"identity\"") == 1);
  for (const char* tick : {">0.01</text>", ">0.1</text>", ">1</text>", ">10</text>", ">100</text>"})
    CHECK_MESSAGE(text.find(tick) != std::string::npos, tick);
}

TEST_CASE("svg plot: a band without points is a legend entry only, a line with a NaN has a gap") {
  svg::Band shown{"", {1, 2, 3}, {1, 1, 1}, {2, 2, 2}, ""};
  svg::Band legendOnly{"90 % band", {}, {}, {}, "#777"};
  svg::Series line;
  line.style = svg::Style::line;
  line.x = {1, 2, 3, 4};
  line.y = {1, std::nan(""), 3, 4};
  const std::string text = svg::renderSvg({{shown, legendOnly}, {line}, {}});
  CHECK(countOf(text, "<polygon class=\"band\"") == 1);
  CHECK(text.find(">90 % band</text>") != std::string::npos);
  CHECK(countOf(text, " M") == 1);  // the pen lifts once, after the gap
}

TEST_CASE("svg plot: an unwritable path is an error naming it") {
  const std::string path = (std::filesystem::temp_directory_path() / "blt_no_such_dir_svg" / "x.svg").string();
  CHECK_THROWS_WITH_AS(svg::writePlot(path, {}, {}), doctest::Contains("blt_no_such_dir_svg/x.svg: cannot open"),
                       InputError);
}
