//! How the figures tell their lines apart: a [`Line`] is a label, a colour,
//! a width and a dash pattern, drawn the same way in the chart and in the
//! legend; legends are drawn beside the chart (never over the data); titles
//! are sized to fit the image width.

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

/// Dash pattern of a line, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Dash {
    /// A solid line.
    Solid,
    /// Dashes of this length with gaps of this length.
    Dashed(u32, u32),
}

/// One line of a figure and its legend entry.
#[derive(Debug, Clone)]
pub(crate) struct Line {
    /// The legend text.
    pub(crate) label: String,
    /// The colour.
    pub(crate) color: RGBColor,
    /// Stroke width, pixels.
    pub(crate) width: u32,
    /// Dash pattern.
    pub(crate) dash: Dash,
}

impl Line {
    /// A line labelled `label`.
    pub(crate) fn new(label: impl Into<String>, color: RGBColor, width: u32, dash: Dash) -> Line {
        Line {
            label: label.into(),
            color,
            width,
            dash,
        }
    }

    fn style(&self) -> ShapeStyle {
        self.color.stroke_width(self.width)
    }

    /// Draw `points` into `chart` in this line's style.
    pub(crate) fn draw<DB, CT>(
        &self,
        chart: &mut ChartContext<'_, DB, CT>,
        points: Vec<(f64, f64)>,
    ) -> Result<(), String>
    where
        DB: DrawingBackend,
        CT: CoordTranslate<From = (f64, f64)>,
    {
        let style = self.style();
        match self.dash {
            Dash::Solid => chart
                .draw_series(LineSeries::new(points, style))
                .map(|_| ())
                .map_err(|e| e.to_string()),
            Dash::Dashed(on, off) => chart
                .draw_series(DashedLineSeries::new(points, on, off, style))
                .map(|_| ())
                .map_err(|e| e.to_string()),
        }
    }

    /// The legend's sample of this line, `len` pixels from `(x, y)`.
    fn sample<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        x: i32,
        y: i32,
        len: i32,
    ) -> Result<(), String> {
        let pts = vec![(x, y), (x + len, y)];
        match self.dash {
            Dash::Solid => area.draw(&PathElement::new(pts, self.style())),
            Dash::Dashed(on, off) => area.draw(&DashedPathElement::new(pts, on, off, self.style())),
        }
        .map_err(|e| e.to_string())
    }
}

/// Height in pixels of a legend of `n` entries in `cols` columns at `font_px`.
pub(crate) fn legend_height(n: usize, cols: usize, font_px: u32) -> u32 {
    let rows = n.div_ceil(cols.max(1)) as u32;
    rows * (font_px + 8) + 12
}

/// Draw a legend of `lines` into `area` (a strip beside or below the chart):
/// `cols` columns, each entry a 44-pixel sample of the line and its label.
pub(crate) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    lines: &[Line],
    cols: usize,
    font_px: u32,
    left_px: i32,
) -> Result<(), String> {
    let cols = cols.max(1);
    let (w, _) = area.dim_in_pixel();
    let col_w = (w as i32 - left_px) / cols as i32;
    let row_h = font_px as i32 + 8;
    let font = ("sans-serif", font_px).into_font();
    for (k, line) in lines.iter().enumerate() {
        let (row, col) = ((k / cols) as i32, (k % cols) as i32);
        let x = left_px + col * col_w;
        let y = 6 + row * row_h + row_h / 2;
        line.sample(area, x, y, 44)?;
        area.draw(&Text::new(
            line.label.clone(),
            (x + 52, y - font_px as i32 / 2 - 1),
            font.clone(),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A font size (pixels) at which `text` fits `width_px`, at most `max_px`
/// and at least 14 (DejaVu Sans averages about 0.55 em per character).
pub(crate) fn title_px(text: &str, width_px: u32, max_px: u32) -> u32 {
    let chars = text.chars().count().max(1) as f64;
    let fit = (0.94 * width_px as f64 / (0.55 * chars)).floor() as u32;
    fit.clamp(14, max_px)
}

/// A light tint of a colour (two parts white).
pub(crate) fn light(c: RGBColor) -> RGBColor {
    let l = |x: u8| ((x as u16 + 2 * 255) / 3) as u8;
    RGBColor(l(c.0), l(c.1), l(c.2))
}
