"""Dataset builder: filters, automatic annotation, descriptions, (text, motion) and (audio, motion) pairs,
storage (Parquet), the Ray build and its report."""
