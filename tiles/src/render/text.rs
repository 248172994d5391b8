//! Labels on the tiles: embedded-graphics' monospaced bitmap fonts (no font file to ship),
//! drawn light with a dark halo so they read on any ground.

use std::convert::Infallible;

use embedded_graphics::mono_font::MonoTextStyle;
use embedded_graphics::mono_font::ascii::{FONT_6X13_BOLD, FONT_10X20};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{DrawTarget, OriginDimensions, Point, RgbColor as _, Size};
use embedded_graphics::text::{Alignment, Baseline, Text, TextStyleBuilder};
use embedded_graphics::{Drawable as _, Pixel};
use tiny_skia::Pixmap;

/// How big a label is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Size2 {
    /// The world's name (10 × 20 px characters).
    Title,
    /// A road's or an area's name (6 × 13 px, bold).
    Name,
}

/// A pixmap as embedded-graphics' drawing target: opaque pixels, anything outside clipped.
struct Target<'a>(&'a mut Pixmap);

impl OriginDimensions for Target<'_> {
    fn size(&self) -> Size {
        Size::new(self.0.width(), self.0.height())
    }
}

impl DrawTarget for Target<'_> {
    type Color = Rgb888;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<Rgb888>>,
    {
        let (w, h) = (self.0.width() as i32, self.0.height() as i32);
        let data = self.0.data_mut();
        for Pixel(p, c) in pixels {
            if (0..w).contains(&p.x) && (0..h).contains(&p.y) {
                let i = 4 * (p.y * w + p.x) as usize;
                data[i..i + 4].copy_from_slice(&[c.r(), c.g(), c.b(), 255]);
            }
        }
        Ok(())
    }
}

/// Draws `text` centred on `(x, y)` (tile pixels; may lie outside the tile, whose part of the
/// label is then drawn).
pub(super) fn label(pixmap: &mut Pixmap, text: &str, x: f64, y: f64, size: Size2) {
    // Far outside: nothing of it can show (and the integers stay small).
    if !(x.abs() < 4_000.0 && y.abs() < 4_000.0) {
        return;
    }
    let font = match size {
        Size2::Title => &FONT_10X20,
        Size2::Name => &FONT_6X13_BOLD,
    };
    let layout = TextStyleBuilder::new()
        .alignment(Alignment::Center)
        .baseline(Baseline::Middle)
        .build();
    let at = Point::new(x.round() as i32, y.round() as i32);
    let mut target = Target(pixmap);
    let halo = MonoTextStyle::new(font, Rgb888::new(16, 22, 18));
    for (dx, dy) in [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ] {
        let _ =
            Text::with_text_style(text, at + Point::new(dx, dy), halo, layout).draw(&mut target);
    }
    let ink = MonoTextStyle::new(font, Rgb888::new(236, 240, 228));
    let _ = Text::with_text_style(text, at, ink, layout).draw(&mut target);
}
