"""
Runs on disk and in memory: rosbag2 I/O, output encoding, histories, figures (no rclpy).

Import rule: may import ``train_dynamics.topics``, ``physics`` and ``simulation``, rosbags,
numpy and matplotlib; never rclpy or ROS message packages, nor the ``ros`` or ``cli`` layers.

- :mod:`.bags`: rosbag2 directories written (:class:`~.bags.BagRecorder`) with ``rosbags``,
  its ``metadata.yaml`` (:mod:`.bag_metadata`) and rows of pre-encoded MCAP records
  (:mod:`.mcap_rows`); :mod:`.bag_read`: bags read (``bags`` re-exports its names);
- :mod:`.messages`: ``rosbags`` message objects (Jazzy typestore), :mod:`.cdr`: the direct
  CDR encoders of the hot output path;
- :mod:`.outputs`: the bytes of the output topics and the run's ``custom_data`` (node and
  offline command alike);
- :mod:`.inputs`: brake inputs read from a bag, :mod:`.sinks`: where the offline run loop
  puts its samples;
- :mod:`.history`: time histories as arrays, :mod:`.plots`: the figures (matplotlib),
  :mod:`.summary`: the curves of ``compare``, :mod:`.metrics_report`: the run metrics
  written as ``summary.json``, ``summary.md`` and figures (``report``), a sweep's figures.
"""
