"""Video files from RGB frames: MP4 (H.264) through imageio-ffmpeg, animated GIF through Pillow.

Why two: MP4 is small and plays everywhere, but needs an encoder; `imageio-ffmpeg` is a wheel that
ships its own ffmpeg binary, so it installs from PyPI like everything else (pinned in
requirements.txt). Without it, a GIF still works (Pillow), only larger: frames are quantised on
arrival to one shared palette (no flicker, 1 byte per pixel in memory) and written on close,
with frame delays (whole hundredths of a second in GIF) that add up to real time.
A video is written to `<name>.part<suffix>` and renamed when complete, so a file with the final
name is never a truncated one.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from gwr_predictor.files.user_files import PendingFile
from gwr_predictor.pipeline.errors import PipelineError

FORMATS = (".mp4", ".gif")
MP4_CRF = 28  # H.264 quality: flat colours and few moving pixels compress far below 10 MB a minute
GIF_COLOURS = 64
GIF_MAX_FRAMES = 4000  # frames are held in memory until close: bounded


def mp4_available() -> bool:
    """Whether the MP4 encoder (imageio-ffmpeg's bundled ffmpeg) can be used."""
    try:
        import imageio_ffmpeg

        return Path(imageio_ffmpeg.get_ffmpeg_exe()).is_file()
    except (ImportError, RuntimeError, OSError):
        return False


def default_suffix() -> str:
    """.mp4 when an encoder is installed, .gif otherwise."""
    return ".mp4" if mp4_available() else ".gif"


class VideoWriter:
    """Frames (HxWx3 uint8, all one size) -> one video file; use as a context manager."""

    def __init__(self, path: str | os.PathLike[str], fps: float, size: tuple[int, int]) -> None:
        self.path = Path(path)
        self.suffix = self.path.suffix.lower()
        if self.suffix not in FORMATS:
            raise PipelineError(f"{self.path}: unknown video format {self.path.suffix!r}; use one of {FORMATS}")
        if not (0.5 <= fps <= 60.0):
            raise PipelineError(f"{self.path}: fps must be within 0.5..60, got {fps!r}")
        self.width, self.height = int(size[0]), int(size[1])
        if self.suffix == ".mp4" and (self.width % 16 or self.height % 16):
            raise PipelineError(f"{self.path}: MP4 frames must be multiples of 16 px, got {self.width}x{self.height}")
        if self.suffix == ".mp4" and not mp4_available():
            raise PipelineError(f"{self.path}: no MP4 encoder: `pip install imageio-ffmpeg==0.6.0` or write a .gif")
        self.fps = float(fps)
        self.frames = 0
        self._pending: PendingFile | None = None
        self._mp4: Any = None
        self._gif: list[Any] = []
        self._palette: Any = None
        self._open = False

    def __enter__(self) -> VideoWriter:
        self.open()
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()

    def open(self) -> None:
        """Check the path and create the temporary file the frames go to (`user_files.PendingFile`)."""
        self._pending = PendingFile(self.path, "video", PipelineError)
        if self.suffix == ".mp4":
            import imageio_ffmpeg

            self._mp4 = imageio_ffmpeg.write_frames(
                str(self._pending.tmp), (self.width, self.height), fps=self.fps, codec="libx264", quality=None,
                pix_fmt_out="yuv420p", macro_block_size=16, ffmpeg_log_level="error",
                output_params=["-crf", str(MP4_CRF), "-preset", "veryfast", "-movflags", "+faststart"])
            self._mp4.send(None)  # starts ffmpeg
        self._open = True

    def write(self, frame: np.ndarray) -> None:
        """Append one frame."""
        if not self._open:
            raise PipelineError(f"{self.path}: video writer is not open (use it as a context manager)")
        frame = np.ascontiguousarray(frame, dtype=np.uint8)
        if frame.shape != (self.height, self.width, 3):
            raise PipelineError(f"{self.path}: frame {self.frames} is {frame.shape}, expected "
                                f"{(self.height, self.width, 3)}")
        if self._mp4 is not None:
            try:
                self._mp4.send(frame)
            except (OSError, RuntimeError) as err:
                self.abort()
                raise PipelineError(f"{self.path}: the encoder failed at frame {self.frames}: {err}") from err
        else:
            if len(self._gif) >= GIF_MAX_FRAMES:
                self.abort()
                raise PipelineError(f"{self.path}: more than {GIF_MAX_FRAMES} GIF frames; shorten --seconds, lower "
                                    f"--fps or write an .mp4")
            from PIL import Image

            image = Image.fromarray(frame)
            if self._palette is None:
                self._palette = image.quantize(GIF_COLOURS, method=Image.Quantize.MEDIANCUT)
            self._gif.append(image.quantize(palette=self._palette, dither=Image.Dither.NONE))
        self.frames += 1

    def close(self) -> None:
        """Finish the file and give it its name (idempotent)."""
        if not self._open:
            return
        self._open = False
        try:
            if self._mp4 is not None:
                self._mp4.close()
                self._mp4 = None
            else:
                if not self._gif:
                    raise PipelineError(f"{self.path}: no frame written")
                first, *rest = self._gif
                # GIF delays are whole hundredths of a second: spread the rounding so time stays real
                ticks = np.round(np.arange(len(self._gif) + 1) * 100.0 / self.fps)
                delays = [max(10, int(v) * 10) for v in np.diff(ticks)]
                assert self._pending is not None  # set by open
                first.save(self._pending.tmp, format="GIF", save_all=True, append_images=rest, duration=delays,
                           loop=0)
                self._gif = []
        except (OSError, RuntimeError) as err:
            self.abort()
            raise PipelineError(f"{self.path}: cannot finish the video: {err}") from err
        if self._pending is not None:
            self._pending.commit()

    def abort(self) -> None:
        """Drop the partial file."""
        self._open = False
        if self._mp4 is not None:
            try:
                self._mp4.close()
            except (OSError, RuntimeError):
                pass
            self._mp4 = None
        self._gif = []
        if self._pending is not None:
            self._pending.discard()


def open_video(path: str | os.PathLike[str], fps: float, size: tuple[int, int]) -> VideoWriter:
    """A VideoWriter for `path` (format from the suffix: .mp4 or .gif)."""
    return VideoWriter(path, fps, size)
